//! The command line's arguments, parsed and checked before anything runs: what `knotwork`
//! accepts, and the job and output files a `tessellate` command turns into. Running the
//! commands is the binary's (src/bin/knotwork.rs); this part is pure, so the argument fuzz
//! target and the tests reach all of it.

use crate::TessOptions;
use crate::backend::Backend;
use crate::io::{MeshFormat, SceneFormat};
use crate::mesh::Tolerance;
use clap::{Parser, Subcommand, ValueEnum};
use std::path::PathBuf;

/// `knotwork`'s arguments.
#[derive(Parser)]
#[command(
    name = "knotwork",
    version,
    about = "Tessellates Bezier, B-spline and NURBS surfaces into triangle meshes"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

impl Cli {
    /// Parses `args` (the program name first) as the binary does, without exiting: the
    /// error carries the message `knotwork` would print.
    pub fn try_parse_args<I, T>(args: I) -> Result<Cli, clap::Error>
    where
        I: IntoIterator<Item = T>,
        T: Into<std::ffi::OsString> + Clone,
    {
        Cli::try_parse_from(args)
    }
}

/// A hint for the commonest slip: a file named where the subcommand goes (`knotwork
/// teapot.bpt -o teapot.obj`). `Some` when clap rejected an unknown subcommand that looks
/// like a path (it has an extension or exists), `None` for any other error.
pub fn missing_subcommand_tip(error: &clap::Error) -> Option<String> {
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    if error.kind() != ErrorKind::InvalidSubcommand {
        return None;
    }
    let Some(ContextValue::String(word)) = error.get(ContextKind::InvalidSubcommand) else {
        return None;
    };
    let path = std::path::Path::new(word);
    (path.extension().is_some() || path.exists()).then(|| {
        format!(
            "tip: to mesh '{word}', name the subcommand first: knotwork tessellate {word} -o OUTPUT"
        )
    })
}

/// The subcommands.
#[derive(Subcommand)]
pub enum Command {
    /// Tessellate surface files (.obj free-form, .bpt, .json, .igs/.iges, .stp/.step) into mesh files (.obj, .ply, .stl, .glb).
    ///
    /// Trimmed faces (IGES) are meshed to a tolerance: --tolerance or --tolerance-rel, else
    /// 1e-3 of the model's diagonal. A face that cannot be read is reported by entity and
    /// reason, the rest of the file is written, and the exit status is 1.
    ///
    /// One input and an output file name: writes that file. Several inputs, a directory of
    /// inputs, or an output that is a directory: writes OUTPUT/NAME.FORMAT for each (NAME:
    /// the input's file name), files in parallel. The GPU computes in f32 (positions within
    /// 1e-5 of each surface's size); `--backend cpu` gives the f64 reference.
    Tessellate {
        /// Input files or directories (their .obj, .bpt, .json, .igs, .iges, .stp and .step files).
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        /// Output file, a directory for several inputs, or `-` for standard output (with
        /// `--format`).
        #[arg(short, long)]
        output: PathBuf,
        /// Vertices per surface, NUxNV (u along the first number; default 33x33); a JSON
        /// surface's own `grid` wins. Trimmed faces and solids are meshed to a tolerance
        /// whatever the grid.
        #[arg(long, value_parser = parse_grid)]
        grid: Option<(u32, u32)>,
        /// Instead of a grid, sample every surface so that the mesh stays within this
        /// distance of it (model units): rates from a proven bound, per knot span and within it.
        #[arg(long, value_parser = parse_tolerance, allow_hyphen_values = true, conflicts_with_all = ["grid", "tolerance_rel"])]
        tolerance: Option<f64>,
        /// As --tolerance, as a fraction of the diagonal of the file's control-point box
        /// (e.g. 1e-3).
        #[arg(long, value_parser = parse_tolerance, allow_hyphen_values = true, conflicts_with = "grid")]
        tolerance_rel: Option<f64>,
        /// Instead of a grid (or beside a tolerance), sample so that no triangle edge is
        /// longer than this (model units).
        #[arg(long, value_parser = parse_tolerance, allow_hyphen_values = true, conflicts_with = "grid")]
        max_edge: Option<f64>,
        /// Instead of a grid (or beside a tolerance), sample so that the surface normals at
        /// the two ends of any triangle edge differ by at most this many degrees (inside each
        /// surface, away from poles and collapsed edges).
        #[arg(long, value_parser = parse_angle, allow_hyphen_values = true, conflicts_with = "grid")]
        max_angle: Option<f64>,
        /// At most this many triangles per file: with --tolerance or --tolerance-rel, a file
        /// that needs more is refused; without, each file is sampled to the finest tolerance
        /// that fits (chosen from the plans, printed in the summary).
        #[arg(long, value_parser = parse_count, conflicts_with = "grid")]
        max_triangles: Option<u64>,
        /// Which tessellator runs.
        #[arg(long, value_enum, default_value_t = Backend::Auto)]
        backend: Backend,
        /// Output format (default: the output's extension; obj in a directory).
        #[arg(long, value_enum)]
        format: Option<OutputFormat>,
        /// Input format (default: each input's extension).
        #[arg(long, value_enum)]
        input_format: Option<InputFormat>,
        /// Merge vertices that coincide across patch edges and drop collapsed triangles.
        #[arg(long)]
        weld: bool,
        /// Points per curve polyline (OBJ `l`, glTF LINE_STRIP); a JSON curve's own `samples` wins.
        #[arg(long, default_value_t = 65, value_parser = clap::value_parser!(u32).range(2..))]
        samples: u32,
        /// Memory one file's mesh may take, e.g. 512M or 4G (default: half the machine's
        /// memory); a file that needs more is refused before anything is allocated. A grid
        /// mesh written to PLY or glb on the CPU streams to its file and is not limited.
        #[arg(long, value_parser = parse_bytes)]
        max_memory: Option<u64>,
    },
    /// Render the tessellated surfaces of INPUT to a PNG (headless, on the GPU adapter).
    Render {
        input: PathBuf,
        /// Output image (.png).
        #[arg(short, long)]
        output: PathBuf,
        /// Image size, WxH.
        #[arg(long, default_value = "800x600", value_parser = parse_size)]
        size: (u32, u32),
        /// Vertices per surface, NUxNV; a JSON surface's own `grid` wins.
        #[arg(long, default_value = "33x33", value_parser = parse_grid)]
        grid: (u32, u32),
        /// Draw the triangle edges.
        #[arg(long)]
        wireframe: bool,
        /// Draw the control nets.
        #[arg(long)]
        control_net: bool,
        /// Where to look from: front, back, left, right, top, bottom, iso, or AZIMUTH,ELEVATION
        /// in degrees (azimuth about the up axis, 0 from +x; elevation above the horizon).
        #[arg(long, default_value = "iso", value_parser = parse_view, allow_hyphen_values = true)]
        view: crate::render::View,
        /// The model's up axis: x, y (the tea set's .bpt files) or z.
        #[arg(long, value_enum, default_value_t = UpAxis::Z)]
        up: UpAxis,
        /// Frame the tessellated model tightly as seen from the view (default: the sphere
        /// around its control points, which fits every view).
        #[arg(long)]
        fit: bool,
    },
    /// List the GPU adapters and the limits that matter to knotwork.
    Info,
    /// Run the GPU-vs-CPU conformance suite on this machine's adapter.
    Conformance {
        /// Instead, write the suite's kernel inputs and f64 expectations to this directory,
        /// to run the kernels on another WebGPU implementation (tests/webgpu runs them in
        /// Chromium's); needs no adapter.
        #[arg(long, value_name = "DIR")]
        export: Option<PathBuf>,
    },
}

/// The `--format` values.
#[derive(Clone, Copy, ValueEnum)]
pub enum OutputFormat {
    Obj,
    Ply,
    Stl,
    Glb,
}

/// The `--input-format` values.
#[derive(Clone, Copy, ValueEnum)]
pub enum InputFormat {
    Obj,
    Bpt,
    Json,
    Iges,
    Step,
}

/// Parses `--grid`: NUxNV, each side at least 2 vertices.
pub fn parse_grid(text: &str) -> Result<(u32, u32), String> {
    let (u, v) = text
        .split_once(['x', 'X'])
        .ok_or("expected NUxNV, e.g. 33x33")?;
    let parse = |s: &str| {
        s.trim()
            .parse::<u32>()
            .map_err(|_| format!("`{s}` is not a vertex count"))
    };
    let (u, v) = (parse(u)?, parse(v)?);
    if u < 2 || v < 2 {
        return Err("each side of the grid needs at least 2 vertices".into());
    }
    Ok((u, v))
}

/// The `--up` values.
#[derive(Clone, Copy, ValueEnum)]
pub enum UpAxis {
    X,
    Y,
    Z,
}

/// Parses `--view`: a named view or "azimuth,elevation" in degrees.
pub fn parse_view(text: &str) -> Result<crate::render::View, String> {
    use crate::render::View;
    Ok(match text {
        "front" => View::FRONT,
        "back" => View::BACK,
        "left" => View::LEFT,
        "right" => View::RIGHT,
        "top" => View::TOP,
        "bottom" => View::BOTTOM,
        "iso" => View::ISO,
        _ => {
            let angles = text.split_once(',').and_then(|(a, e)| {
                Some((a.trim().parse::<f32>().ok()?, e.trim().parse::<f32>().ok()?))
            });
            match angles {
                Some((azimuth, elevation)) if (-90.0..=90.0).contains(&elevation) => {
                    View { azimuth, elevation }
                }
                _ => {
                    return Err(format!(
                        "`{text}`: expected front, back, left, right, top, bottom, iso or AZIMUTH,ELEVATION (elevation in -90..=90)"
                    ));
                }
            }
        }
    })
}

/// Parses `--size`: WxH pixels, each in 1..=8192.
pub fn parse_size(text: &str) -> Result<(u32, u32), String> {
    let (w, h) = text
        .split_once(['x', 'X'])
        .ok_or("expected WxH, e.g. 800x600")?;
    let parse = |s: &str| {
        s.trim()
            .parse::<u32>()
            .ok()
            .filter(|n| (1..=8192).contains(n))
            .ok_or(format!("`{s}` is not a size in 1..=8192"))
    };
    Ok((parse(w)?, parse(h)?))
}

/// What to do with every input.
pub struct Job {
    pub options: TessOptions,
    pub format: Option<MeshFormat>,
    pub input_format: Option<SceneFormat>,
    pub weld: bool,
    pub samples: u32,
    /// Bytes one file's mesh may take (halved when welding, which copies it).
    pub memory_budget: u64,
    /// Triangles one file's mesh may have (`--max-triangles`).
    pub max_triangles: Option<u64>,
    /// Whether `--grid` was given: trimmed faces and solids, which it does not apply to,
    /// are then pointed out.
    pub grid_given: bool,
}

/// The options of `--grid`, `--tolerance`, `--tolerance-rel`, `--max-edge` and
/// `--max-angle` (at most one tolerance, and none with `--grid`: clap refuses those).
pub fn tess_options(
    grid: Option<(u32, u32)>,
    tolerance: Option<f64>,
    tolerance_rel: Option<f64>,
    max_edge: Option<f64>,
    max_angle: Option<f64>,
) -> TessOptions {
    let tolerance = match (tolerance, tolerance_rel) {
        (Some(t), _) => Some(Tolerance::Absolute(t)),
        (None, r) => r.map(Tolerance::Relative),
    };
    let (grid_u, grid_v) =
        grid.unwrap_or((TessOptions::DEFAULT.grid_u, TessOptions::DEFAULT.grid_v));
    TessOptions::DEFAULT
        .with_grid(grid_u, grid_v)
        .with_limits(tolerance, max_edge, max_angle)
}

/// Parses a count of at least 1: digits (`250000`), a whole number in scientific notation
/// (`2.5e5`), or with a k or M suffix (`250k`, `1.5M`).
pub fn parse_count(text: &str) -> Result<u64, String> {
    let text = text.trim();
    let (number, scale) = match text.strip_suffix(['k', 'K']) {
        Some(number) => (number, 1e3),
        None => match text.strip_suffix('M') {
            Some(number) => (number, 1e6),
            None => (text, 1.0),
        },
    };
    if let (Ok(count), 1.0) = (number.parse::<u64>(), scale) {
        return if count >= 1 {
            Ok(count)
        } else {
            Err("the count must be at least 1".into())
        };
    }
    match number.parse::<f64>().map(|n| n * scale) {
        Ok(value) if value >= 1.0 && value.fract() == 0.0 && value <= 1e18 => Ok(value as u64),
        Ok(value) => Err(format!(
            "{value} is not a count: it must be a whole number of at least 1"
        )),
        Err(_) => Err(format!(
            "`{text}` is not a count (e.g. 250000, 2.5e5 or 250k)"
        )),
    }
}

/// Parses a tolerance or a length: a finite number greater than 0.
pub fn parse_tolerance(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(value) if value.is_finite() && value > 0.0 => Ok(value),
        Ok(value) => Err(format!(
            "{value} is not a tolerance: it must be greater than 0"
        )),
        Err(_) => Err(format!("`{text}` is not a number")),
    }
}

/// Parses an angle in degrees, greater than 0 and less than 180.
pub fn parse_angle(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(value) if value > 0.0 && value < 180.0 => Ok(value),
        Ok(value) => Err(format!(
            "{value} is not an angle between normals: it must be greater than 0 and less than 180 (degrees)"
        )),
        Err(_) => Err(format!("`{text}` is not a number of degrees")),
    }
}

impl Job {
    /// The job a `tessellate` command's options describe; `memory_budget` is `--max-memory`
    /// or the caller's default.
    pub fn new(
        options: TessOptions,
        format: Option<OutputFormat>,
        input_format: Option<InputFormat>,
        weld: bool,
        samples: u32,
        memory_budget: u64,
    ) -> Self {
        Job {
            options,
            format: format.map(OutputFormat::mesh_format),
            input_format: input_format.map(InputFormat::scene_format),
            weld,
            samples,
            memory_budget,
            max_triangles: None,
            grid_given: false,
        }
    }

    /// The job with whether `--grid` was given.
    pub fn with_grid_given(self, grid_given: bool) -> Self {
        Job { grid_given, ..self }
    }

    /// The job with `--max-triangles`.
    pub fn with_max_triangles(self, max_triangles: Option<u64>) -> Self {
        Job {
            max_triangles,
            ..self
        }
    }
}

/// Parses a byte count: a number, optionally followed by K, M, G or T (powers of 1024).
pub fn parse_bytes(text: &str) -> Result<u64, String> {
    let text = text.trim();
    let (digits, unit) = match text.char_indices().find(|(_, c)| !c.is_ascii_digit()) {
        Some((at, _)) => text.split_at(at),
        None => (text, ""),
    };
    let scale: u64 = match unit.to_ascii_uppercase().trim_end_matches(['B', 'I']) {
        "" => 1,
        "K" => 1 << 10,
        "M" => 1 << 20,
        "G" => 1 << 30,
        "T" => 1 << 40,
        _ => return Err(format!("`{text}`: expected bytes like 512M or 4G")),
    };
    let number: u64 = digits
        .parse()
        .map_err(|_| format!("`{text}`: expected bytes like 512M or 4G"))?;
    number
        .checked_mul(scale)
        .ok_or_else(|| format!("`{text}` is more bytes than a u64 counts"))
}

impl OutputFormat {
    /// The mesh format this names.
    pub fn mesh_format(self) -> MeshFormat {
        match self {
            OutputFormat::Obj => MeshFormat::Obj,
            OutputFormat::Ply => MeshFormat::Ply,
            OutputFormat::Stl => MeshFormat::Stl,
            OutputFormat::Glb => MeshFormat::Glb,
        }
    }
}

impl InputFormat {
    /// The scene format this names.
    pub fn scene_format(self) -> SceneFormat {
        match self {
            InputFormat::Obj => SceneFormat::Obj,
            InputFormat::Bpt => SceneFormat::Bpt,
            InputFormat::Json => SceneFormat::Json,
            InputFormat::Iges => SceneFormat::Iges,
            InputFormat::Step => SceneFormat::Step,
        }
    }
}

impl UpAxis {
    /// The render axis this names.
    #[cfg(feature = "render")]
    pub fn axis(self) -> crate::render::Axis {
        match self {
            UpAxis::X => crate::render::Axis::X,
            UpAxis::Y => crate::render::Axis::Y,
            UpAxis::Z => crate::render::Axis::Z,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A negative azimuth is a value, not a flag: `--view -90,50` parses.
    #[test]
    fn negative_view_angles_parse() {
        let cli = Cli::try_parse_args([
            "knotwork", "render", "a.bpt", "-o", "a.png", "--view", "-90,50",
        ])
        .unwrap();
        let Command::Render { view, .. } = cli.command else {
            panic!("not a render command")
        };
        assert_eq!((view.azimuth, view.elevation), (-90.0, 50.0));
    }

    /// A file where the subcommand goes gets a tip naming `tessellate`; a misspelt
    /// subcommand gets clap's own suggestion only.
    #[test]
    fn a_file_in_place_of_the_subcommand_gets_a_tip() {
        let error = Cli::try_parse_args(["knotwork", "teapot.bpt", "-o", "t.obj"])
            .err()
            .expect("a file is not a subcommand");
        let tip = missing_subcommand_tip(&error).expect("a tip for a file name");
        assert!(
            tip.contains("knotwork tessellate teapot.bpt -o OUTPUT"),
            "{tip}"
        );
        let error = Cli::try_parse_args(["knotwork", "tesselate", "a.bpt", "-o", "a.obj"])
            .err()
            .expect("a misspelt subcommand");
        assert_eq!(missing_subcommand_tip(&error), None);
        let error = Cli::try_parse_args(["knotwork", "render", "a.bpt"])
            .err()
            .expect("render needs -o");
        assert_eq!(missing_subcommand_tip(&error), None);
    }

    /// Triangle budgets read as users write them; fractions, zero and words are refused.
    #[test]
    fn counts_parse_in_the_forms_users_write() {
        for (text, count) in [
            ("250000", 250_000),
            ("2.5e5", 250_000),
            ("250k", 250_000),
            ("1.5M", 1_500_000),
            ("1e4", 10_000),
        ] {
            assert_eq!(parse_count(text), Ok(count), "{text}");
        }
        for text in ["0", "0.5", "1.5", "-3", "many", "", "1e30"] {
            assert!(parse_count(text).is_err(), "{text}");
        }
    }
}
