//! The knotwork command line: parse arguments into a command, then run it.

use clap::{Parser, Subcommand, ValueEnum};
use knotwork::{CpuTessellator, GpuContext, GpuTessellator, TessOptions, Tessellator};
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
    ///
    /// The GPU computes in f32 (positions within 1e-5 of each surface's size); `--backend cpu`
    /// gives the f64 reference.
    Tessellate {
        input: PathBuf,
        /// Output mesh file.
        #[arg(short, long)]
        output: PathBuf,
        /// Vertices per surface, NUxNV (u along the first number).
        #[arg(long, default_value = "33x33", value_parser = parse_grid)]
        grid: (u32, u32),
        /// Which tessellator runs.
        #[arg(long, value_enum, default_value_t = Backend::Auto)]
        backend: Backend,
    },
    /// List the GPU adapters and the limits that matter to knotwork.
    Info,
}

#[derive(Clone, Copy, ValueEnum)]
enum Backend {
    /// The GPU when an adapter exists, else the CPU.
    Auto,
    /// wgpu compute shaders, f32.
    Gpu,
    /// The f64 reference path, on all cores.
    Cpu,
}

/// The tessellator `backend` asks for.
fn tessellator(backend: Backend) -> knotwork::Result<Box<dyn Tessellator>> {
    Ok(match backend {
        Backend::Cpu => Box::new(CpuTessellator),
        Backend::Gpu => Box::new(GpuTessellator::new()?),
        Backend::Auto => match GpuTessellator::new() {
            Ok(gpu) => Box::new(gpu),
            Err(_) => Box::new(CpuTessellator),
        },
    })
}

/// Adapters, backends, device types, drivers and the limits that decide chunking.
fn info() -> String {
    let instance = knotwork::gpu::headless_instance();
    let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
    let mut out = String::new();
    if adapters.is_empty() {
        out.push_str("no GPU adapter found: `--backend auto` uses the CPU (on Debian, `apt-get install mesa-vulkan-drivers` gives a software adapter)\n");
    }
    for (index, adapter) in adapters.iter().enumerate() {
        let a = adapter.get_info();
        let l = adapter.limits();
        let f = adapter.features();
        out.push_str(&format!(
            "adapter {index}: {}\n  backend {:?}, device type {:?}, driver {} {}\n  max_buffer_size {} MiB, max_storage_buffer_binding_size {} MiB, max_compute_workgroups_per_dimension {}, max_compute_invocations_per_workgroup {}\n  mappable primary buffers: {}, timestamp queries: {}, shader f64: {}\n",
            a.name,
            a.backend,
            a.device_type,
            a.driver,
            a.driver_info,
            l.max_buffer_size >> 20,
            l.max_storage_buffer_binding_size >> 20,
            l.max_compute_workgroups_per_dimension,
            l.max_compute_invocations_per_workgroup,
            f.contains(wgpu::Features::MAPPABLE_PRIMARY_BUFFERS),
            f.contains(wgpu::Features::TIMESTAMP_QUERY),
            f.contains(wgpu::Features::SHADER_F64),
        ));
    }
    match GpuContext::new() {
        Ok(context) => out.push_str(&format!("default adapter (used by --backend gpu|auto): {}", context.adapter_summary())),
        Err(error) => out.push_str(&format!("default adapter: none ({error})")),
    }
    out
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
            let tessellator = tessellator(backend)?;
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
        Command::Info => Ok(info()),
    }
}
