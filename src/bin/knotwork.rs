//! The knotwork command line: parse arguments into a command, then run it.

use clap::{Parser, Subcommand, ValueEnum};
use knotwork::{CpuTessellator, TessOptions, Tessellator};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

#[derive(Parser)]
#[command(name = "knotwork", version, about = "Tessellates Bezier, B-spline and NURBS surfaces into triangle meshes")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Tessellate the surfaces of INPUT (.obj free-form, .bpt) into a mesh file (.obj).
    Tessellate {
        input: PathBuf,
        /// Output mesh file.
        #[arg(short, long)]
        output: PathBuf,
        /// Vertices per surface, NUxNV (u along the first number).
        #[arg(long, default_value = "33x33", value_parser = parse_grid)]
        grid: (u32, u32),
        /// Which tessellator runs.
        #[arg(long, value_enum, default_value_t = Backend::Cpu)]
        backend: Backend,
    },
}

#[derive(Clone, Copy, ValueEnum)]
enum Backend {
    /// The f64 reference path, on all cores.
    Cpu,
}

fn parse_grid(text: &str) -> Result<(u32, u32), String> {
    let (u, v) = text.split_once(['x', 'X']).ok_or("expected NUxNV, e.g. 33x33")?;
    let parse = |s: &str| s.trim().parse::<u32>().map_err(|_| format!("`{s}` is not a vertex count"));
    let (u, v) = (parse(u)?, parse(v)?);
    if u < 2 || v < 2 {
        return Err("each side of the grid needs at least 2 vertices".into());
    }
    Ok((u, v))
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli.command) {
        Ok(summary) => {
            println!("{summary}");
            ExitCode::SUCCESS
        }
        Err(error) => {
            eprintln!("error: {error}");
            ExitCode::FAILURE
        }
    }
}

fn run(command: Command) -> knotwork::Result<String> {
    match command {
        Command::Tessellate { input, output, grid, backend } => {
            let start = Instant::now();
            let scene = knotwork::io::read_scene(&input)?;
            let tessellator = match backend {
                Backend::Cpu => CpuTessellator,
            };
            let mesh = tessellator.tessellate(&scene.surfaces, &TessOptions::DEFAULT.with_grid(grid.0, grid.1))?;
            knotwork::io::write_mesh(&output, &mesh)?;
            Ok(format!(
                "{}: {} surfaces, {} vertices, {} triangles in {:.3} s ({}) -> {}",
                input.display(),
                scene.surfaces.len(),
                mesh.vertex_count(),
                mesh.triangle_count(),
                start.elapsed().as_secs_f64(),
                tessellator.name(),
                output.display()
            ))
        }
    }
}
