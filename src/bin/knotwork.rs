//! The knotwork command line: parse arguments into a command, then run it.

use knotwork::backend::Backend;
use knotwork::cli::{Cli, Command, Job};
use knotwork::io::SceneFormat;
use knotwork::{GpuContext, GpuTessellator, SceneOptions, TessOptions, Tessellator};
use rayon::prelude::*;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// Tessellates on the GPU and renders the batch's own buffers to a PNG; returns whether
/// every part of the file was read.
fn render(
    input: &Path,
    output: &Path,
    grid: (u32, u32),
    options: &knotwork::render::RenderOptions,
) -> knotwork::Result<bool> {
    let start = Instant::now();
    let scene = knotwork::io::read_scene(input)?;
    let context = GpuContext::new()?;
    let defaults = SceneOptions {
        grid: TessOptions::DEFAULT.with_grid(grid.0, grid.1),
        ..SceneOptions::default()
    };
    let dropped = report_reading(input, &scene);
    let batch = knotwork::GpuBatch::from_scene(&context, &scene, &defaults)?;
    batch.dispatch()?;
    let surfaces = scene.surface_list();
    let image = knotwork::render::render(&context, &batch, &surfaces, options)?;
    knotwork::render::save_png(output, &image)?;
    let triangles = batch
        .coons_meshes()
        .iter()
        .chain(batch.trimmed_mesh())
        .chain([batch.mesh()])
        .map(|m| m.index_count as usize / 3)
        .sum::<usize>();
    println!(
        "{}: {}, {}, {} rendered at {}x{} in {:.3} s ({}) -> {}",
        input.display(),
        {
            let (surfaces, shells) = scene_counts(&scene);
            items_summary(surfaces, shells)
        },
        count(scene.curves().count(), "curve"),
        count(triangles, "triangle"),
        options.width,
        options.height,
        start.elapsed().as_secs_f64(),
        context.adapter_summary(),
        output.display()
    );
    Ok(dropped == 0)
}

/// Mesa's drivers print "error: XDG_RUNTIME_DIR is invalid or not set in the environment"
/// when that variable is unset (headless machines, containers, CI), which reads as an error
/// of knotwork's: give the process a private runtime folder (mode 0700, per user) instead.
#[cfg(unix)]
fn quiet_driver_runtime_dir() {
    use std::os::unix::fs::{DirBuilderExt, MetadataExt};
    if std::env::var_os("XDG_RUNTIME_DIR").is_some() {
        return;
    }
    let Ok(me) = std::fs::metadata("/proc/self") else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("knotwork-runtime-{}", me.uid()));
    // It may exist from an earlier run: use it only if it is a folder of this user's.
    let _ = std::fs::DirBuilder::new().mode(0o700).create(&dir);
    if std::fs::metadata(&dir).is_ok_and(|m| m.is_dir() && m.uid() == me.uid()) {
        // SAFETY: called first thing in `main`, before any other thread exists.
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", &dir) };
    }
}

fn main() -> ExitCode {
    #[cfg(unix)]
    quiet_driver_runtime_dir();
    let cli = match Cli::try_parse_args(std::env::args_os()) {
        Ok(cli) => cli,
        Err(error) => {
            // clap's message (or --help, --version) as clap prints it, then a tip for a
            // file given where the subcommand goes; clap's exit status either way.
            let _ = error.print();
            if let Some(tip) = knotwork::cli::missing_subcommand_tip(&error) {
                eprintln!("\n{tip}");
            }
            return ExitCode::from(u8::try_from(error.exit_code()).unwrap_or(2));
        }
    };
    let result = match cli.command {
        Command::Tessellate {
            inputs,
            output,
            grid,
            tolerance,
            tolerance_rel,
            max_edge,
            max_angle,
            max_triangles,
            backend,
            format,
            input_format,
            weld,
            samples,
            max_memory,
        } => {
            let grid_given = grid.is_some();
            let job = Job::new(
                knotwork::cli::tess_options(grid, tolerance, tolerance_rel, max_edge, max_angle),
                format,
                input_format,
                weld,
                samples,
                max_memory.unwrap_or_else(knotwork::scene::default_memory_budget),
            )
            .with_max_triangles(max_triangles)
            .with_grid_given(grid_given);
            tessellate(&inputs, &output, backend, &job)
        }
        Command::Render {
            input,
            output,
            size,
            grid,
            wireframe,
            control_net,
            view,
            up,
            fit,
        } => {
            let options = knotwork::render::RenderOptions {
                width: size.0,
                height: size.1,
                wireframe,
                control_net,
                view,
                up: up.axis(),
                fit,
            };
            render(&input, &output, grid, &options)
        }
        Command::Info => {
            println!("{}", knotwork::backend::adapters_report());
            Ok(true)
        }
        Command::Conformance { export: Some(dir) } => knotwork::conformance::export_suite(&dir)
            .map(|cases| {
                println!("wrote {cases} cases to {}", dir.display());
                true
            }),
        Command::Conformance { export: None } => conformance(),
    };
    match result {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::FAILURE,
        Err(error) => {
            eprintln!("error: {error}");
            ExitCode::FAILURE
        }
    }
}

/// The tessellator `backend` asks for; a job `auto` moves from the GPU to the CPU is noted
/// on stderr.
fn tessellator(backend: Backend) -> knotwork::Result<Box<dyn Tessellator + Send + Sync>> {
    knotwork::backend::tessellator(
        backend,
        Box::new(|e| eprintln!("note: the GPU cannot hold this job ({e}); the CPU tessellates it")),
    )
}

/// Counts for one file.
#[derive(Default)]
struct Tally {
    surfaces: usize,
    shells: Shells,
    curves: usize,
    vertices: usize,
    triangles: usize,
    /// Vertices merged by welding (`None` without `--weld`).
    merged: Option<usize>,
    /// Faces the reader could not read (reported as they were found).
    dropped: usize,
    /// The tolerance `--max-triangles` chose (model units), if it chose one.
    chosen_tolerance: Option<f64>,
    /// (meshes, instances) of a glb that keeps an assembly's instances.
    instanced: Option<(usize, usize)>,
}

impl Tally {
    /// The one line a single file's job prints: "INPUT: SUMMARY in S s (BACKEND) -> TARGET".
    fn line(&self, input: &Path, seconds: f64, backend: &str, target: &str) -> String {
        format!(
            "{}: {} in {seconds:.3} s ({backend}) -> {target}",
            input.display(),
            self.summary()
        )
    }

    /// "N surfaces, N curves, N vertices, N triangles[ (M meshes shown by K instances)][, N
    /// vertices merged][, tolerance T for the triangle budget]".
    fn summary(&self) -> String {
        let instanced = self.instanced.map_or(String::new(), |(meshes, instances)| {
            format!(
                " ({} shown by {})",
                count(meshes, "mesh"),
                count(instances, "instance")
            )
        });
        let merged = self.merged.map_or(String::new(), |m| {
            format!(", {} merged", count(m, "vertex"))
        });
        let chosen = self.chosen_tolerance.map_or(String::new(), |t| {
            format!(", tolerance {t:.3e} for the triangle budget")
        });
        format!(
            "{}, {}, {}, {}{instanced}{merged}{chosen}",
            items_summary(self.surfaces, self.shells),
            count(self.curves, "curve"),
            count(self.vertices, "vertex"),
            count(self.triangles, "triangle"),
        )
    }
}

/// Prints the reader's notes as warnings and the parts it dropped as errors (on stderr);
/// returns how many were dropped.
fn report_reading(input: &Path, scene: &knotwork::Scene) -> usize {
    for note in &scene.notes {
        eprintln!("warning: {}: {note}", input.display());
    }
    for dropped in &scene.dropped {
        eprintln!(
            "error: {}: {} left out: {}",
            input.display(),
            dropped.what,
            dropped.reason
        );
    }
    scene.dropped.len()
}

/// Prints why each face left out of a mesh whose parts came from `items` was left out;
/// returns how many.
fn report_skipped(
    input: &Path,
    scene: &knotwork::Scene,
    defaults: &SceneOptions,
    items: impl Iterator<Item = u32>,
) -> usize {
    let reasons = knotwork::scene::left_out_faces(scene, defaults, items);
    for reason in &reasons {
        eprintln!("error: {}: face left out: {reason}", input.display());
    }
    reasons.len()
}

/// B-rep shells counted: closed ones (solids) and open ones, with their faces.
#[derive(Clone, Copy, Default)]
struct Shells {
    solids: usize,
    open: usize,
    faces: usize,
}

impl std::ops::AddAssign for Shells {
    fn add_assign(&mut self, other: Shells) {
        self.solids += other.solids;
        self.open += other.open;
        self.faces += other.faces;
    }
}

/// "32 surfaces", or with shells "6 solids (25 faces)", "1 solid, 2 open shells (9
/// faces)" (and the surfaces beside them, if any).
fn items_summary(surfaces: usize, shells: Shells) -> String {
    let kinds: Vec<String> = [(shells.solids, "solid"), (shells.open, "open shell")]
        .into_iter()
        .filter(|&(n, _)| n > 0)
        .map(|(n, noun)| count(n, noun))
        .collect();
    let listed = format!("{} ({})", kinds.join(", "), count(shells.faces, "face"));
    match (surfaces, kinds.is_empty()) {
        (_, true) => count(surfaces, "surface"),
        (0, false) => listed,
        _ => format!("{}, {listed}", count(surfaces, "surface")),
    }
}

/// The surfaces and shells of a scene: curves are counted apart.
fn scene_counts(scene: &knotwork::Scene) -> (usize, Shells) {
    let mut shells = Shells::default();
    for item in &scene.items {
        if let knotwork::Geometry::Shell(shell) = &item.geometry {
            if shell.is_closed() {
                shells.solids += 1;
            } else {
                shells.open += 1;
            }
            shells.faces += shell.faces().len();
        }
    }
    let surfaces = scene.items.len() - scene.curves().count() - shells.solids - shells.open;
    (surfaces, shells)
}

/// "1 surface", "2 surfaces", "1 vertex", "3 vertices".
fn count(n: usize, noun: &str) -> String {
    match (n, noun) {
        (1, _) => format!("1 {noun}"),
        (_, "vertex") => format!("{n} vertices"),
        (_, "mesh") => format!("{n} meshes"),
        _ => format!("{n} {noun}s"),
    }
}

fn process(
    input: &Path,
    output: &Path,
    tessellator: &dyn Tessellator,
    job: &Job,
) -> knotwork::Result<Tally> {
    let scene = knotwork::io::read_scene_as(input, job.input_format)?;
    let dropped = report_reading(input, &scene);
    let (surfaces, shells) = scene_counts(&scene);
    let trimmed = scene
        .items
        .iter()
        .filter(|i| matches!(i.geometry, knotwork::Geometry::Trimmed(_)))
        .count();
    if job.grid_given && shells.solids + shells.open + trimmed > 0 {
        eprintln!(
            "warning: {}: --grid does not apply to its {}: they are meshed to {} of the diagonal (--tolerance or --tolerance-rel sets it)",
            input.display(),
            items_summary(trimmed, shells).replace("surface", "trimmed face"),
            knotwork::cpu::TRIMMED_DEFAULT_TOLERANCE_REL
        );
    }
    let budget = if job.weld {
        job.memory_budget / 2
    } else {
        job.memory_budget
    };
    let defaults = SceneOptions {
        grid: job.options,
        samples: job.samples,
        memory_budget: Some(budget),
        skip_failed_faces: true,
        max_triangles: job.max_triangles,
    };
    // The tolerance a triangle budget chose, once, for the summary and the tessellation.
    let defaults = knotwork::scene::fit_triangle_budget(&scene, &defaults)?;
    let chosen = match (job.options.tolerance, defaults.grid.tolerance) {
        (None, Some(knotwork::Tolerance::Absolute(t))) => Some(t),
        _ => None,
    };
    let written = knotwork::io::tessellate_to_file(
        output,
        job.format,
        &scene,
        &defaults,
        tessellator,
        job.weld,
    )?;
    let skipped = report_skipped(input, &scene, &defaults, written.part_items.into_iter());
    Ok(Tally {
        surfaces,
        shells,
        curves: scene.curves().count(),
        vertices: written.vertices,
        triangles: written.triangles,
        merged: written.merged_vertices,
        dropped: dropped + skipped,
        chosen_tolerance: chosen,
        instanced: written.instanced,
    })
}

/// Expands directories into the surface files they hold (sorted), keeps files as given.
fn expand_inputs(inputs: &[PathBuf]) -> knotwork::Result<Inputs> {
    let mut expanded = Inputs::default();
    for input in inputs {
        if input.is_dir() {
            let entries = std::fs::read_dir(input).map_err(|source| knotwork::Error::Io {
                path: input.clone(),
                source,
            })?;
            let (mut found, others): (Vec<PathBuf>, Vec<PathBuf>) = entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.is_file())
                .partition(|p| {
                    p.extension()
                        .and_then(|e| e.to_str())
                        .and_then(SceneFormat::from_extension)
                        .is_some()
                });
            if found.is_empty() {
                return Err(knotwork::Error::NoInputFiles {
                    path: input.clone(),
                    expected: knotwork::io::INPUT_FORMATS,
                });
            }
            found.sort();
            expanded.files.extend(found);
            expanded.skipped.extend(others);
        } else {
            expanded.files.push(input.clone());
        }
    }
    expanded.skipped.sort();
    Ok(expanded)
}

/// The files a batch reads, and the files of its folders it leaves alone (other formats).
#[derive(Default)]
struct Inputs {
    files: Vec<PathBuf>,
    skipped: Vec<PathBuf>,
}

/// `-o -`: one input's mesh to standard output, in `--format` (there is no extension to
/// name one), the summary to standard error. The mesh goes through a temporary file — the
/// writers stream into files they seek in — copied out when complete, so a failed job
/// writes nothing. Binary formats are refused on a terminal.
fn tessellate_to_stdout(
    inputs: &[PathBuf],
    batch: bool,
    backend: Backend,
    job: &Job,
) -> knotwork::Result<bool> {
    let refuse = |what: &str| Err(knotwork::Error::Unsupported { what: what.into() });
    if batch {
        return refuse(
            "several inputs or a folder to standard output (-o -): give an output folder",
        );
    }
    let Some(format) = job.format else {
        return refuse(
            "-o - (standard output) without --format: name the format (obj, ply, stl or glb)",
        );
    };
    let mut stdout = std::io::stdout().lock();
    if format != knotwork::io::MeshFormat::Obj && stdout.is_terminal() {
        return refuse(
            "binary mesh output to a terminal: redirect standard output to a file or a pipe",
        );
    }
    let start = Instant::now();
    let tessellator = tessellator(backend)?;
    let temporary = std::env::temp_dir().join(format!(
        "knotwork-stdout-{}.{}",
        std::process::id(),
        format.extension()
    ));
    let input = &inputs[0];
    let result = process(input, &temporary, tessellator.as_ref(), job).and_then(|tally| {
        let copied = std::fs::File::open(&temporary)
            .and_then(|mut file| std::io::copy(&mut file, &mut stdout))
            .and_then(|_| std::io::Write::flush(&mut stdout))
            // A reader that stops early (`| head`) is not an error of the job.
            .or_else(|e| match e.kind() {
                std::io::ErrorKind::BrokenPipe => Ok(()),
                _ => Err(e),
            });
        copied
            .map(|()| tally)
            .map_err(|source| knotwork::Error::Io {
                path: "standard output".into(),
                source,
            })
    });
    // Gone whether or not the job succeeded (it may not exist).
    let _ = std::fs::remove_file(&temporary);
    let tally = result.map_err(|error| error.naming_file(input))?;
    let seconds = start.elapsed().as_secs_f64();
    eprintln!(
        "{}",
        tally.line(input, seconds, &tessellator.name(), "standard output")
    );
    Ok(tally.dropped == 0)
}

/// Tessellates every input; returns whether all succeeded.
fn tessellate(
    inputs: &[PathBuf],
    output: &Path,
    backend: Backend,
    job: &Job,
) -> knotwork::Result<bool> {
    let start = Instant::now();
    // An output ending in a path separator names a folder, made if missing, like an
    // existing one: `-o meshes/` for one file writes meshes/<stem>.obj.
    let names_folder = output.is_dir()
        || (output.to_string_lossy()).ends_with(|c: char| std::path::is_separator(c));
    let batch = inputs.len() > 1 || inputs.iter().any(|p| p.is_dir()) || names_folder;
    if output == Path::new("-") {
        return tessellate_to_stdout(inputs, batch, backend, job);
    }
    let tessellator = tessellator(backend)?;
    if !batch {
        knotwork::io::refuse_overwriting_inputs(inputs, output)?;
        let tally = process(&inputs[0], output, tessellator.as_ref(), job)
            .map_err(|error| error.naming_file(&inputs[0]))?;
        let seconds = start.elapsed().as_secs_f64();
        let target = output.display().to_string();
        println!(
            "{}",
            tally.line(&inputs[0], seconds, &tessellator.name(), &target)
        );
        return Ok(tally.dropped == 0);
    }
    let Inputs { files, skipped } = expand_inputs(inputs)?;
    // Every input's output, checked for collisions before anything is written.
    let targets = knotwork::io::output_targets(&files, output, job.format)?;
    std::fs::create_dir_all(output).map_err(|source| knotwork::Error::Io {
        path: output.to_path_buf(),
        source,
    })?;
    let progress = if std::io::stderr().is_terminal() {
        indicatif::ProgressBar::new(files.len() as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    let results: Vec<(PathBuf, knotwork::Result<Tally>)> = targets
        .par_iter()
        .map(|(input, target)| {
            let result = process(input, target, tessellator.as_ref(), job);
            progress.inc(1);
            (input.clone(), result)
        })
        .collect();
    progress.finish_and_clear();
    let mut total = Tally::default();
    let mut failed = 0;
    let file_count = results.len();
    for (input, result) in results {
        match result {
            Ok(t) => {
                failed += usize::from(t.dropped > 0);
                total.surfaces += t.surfaces;
                total.shells += t.shells;
                total.curves += t.curves;
                total.vertices += t.vertices;
                total.triangles += t.triangles;
                if let Some(m) = t.merged {
                    *total.merged.get_or_insert(0) += m;
                }
            }
            Err(error) => {
                failed += 1;
                eprintln!("error: {}", error.naming_file(&input));
            }
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    if let Some(first) = skipped.first() {
        println!(
            "skipped {} of other formats in the input folders (e.g. {}); knotwork reads {}",
            count(skipped.len(), "file"),
            first.display(),
            knotwork::io::INPUT_FORMATS
        );
    }
    // In millions a second, or thousands below a tenth of a million (a small part).
    let rate = total.vertices as f64 / seconds;
    let rate = if rate >= 1e5 {
        format!("{:.1} M", rate / 1e6)
    } else {
        format!("{:.1} k", rate / 1e3)
    };
    println!(
        "{} ({failed} failed): {} in {seconds:.3} s, {rate} vertices/s ({}) -> {}",
        count(file_count, "file"),
        total.summary(),
        tessellator.name(),
        output.display()
    );
    Ok(failed == 0)
}

/// Runs the conformance suite on the default adapter; prints a table and a verdict.
fn conformance() -> knotwork::Result<bool> {
    use knotwork::conformance::{
        self, DEGENERATE_NORMAL_BAR, Measured, NORMAL_BAR, POSITION_REL_BAR, TANGENT_REL_BAR,
    };
    let gpu = GpuTessellator::new()?;
    println!("adapter: {}", gpu.context().adapter_summary());
    println!(
        "bars: position {POSITION_REL_BAR:e} of the diagonal (+ f32 rounding), normal {NORMAL_BAR:e} rad ({DEGENERATE_NORMAL_BAR:e} near degenerate points), curve tangent {TANGENT_REL_BAR:e} of its scale"
    );
    println!(
        "{:<48} {:>14} {:>14} {:>14} {:>9}  result",
        "case", "position/diag", "normal (rad)", "degen. (rad)", "uv"
    );
    let outcomes = conformance::run_all(&gpu)?;
    let mut curve_header = false;
    for outcome in &outcomes {
        let result = if outcome.passes() { "pass" } else { "FAIL" };
        match outcome.measured {
            Measured::Surface(report) => println!(
                "{:<48} {:>14.3e} {:>14.3e} {:>14.3e} {:>9.1e}  {result}",
                outcome.name,
                report.worst_position,
                report.worst_normal,
                report.worst_degenerate_normal,
                report.worst_uv,
            ),
            Measured::Curve(report) => {
                if !curve_header {
                    curve_header = true;
                    println!(
                        "{:<48} {:>14} {:>14}  result",
                        "curve case", "position/size", "tangent (rel)"
                    );
                }
                println!(
                    "{:<48} {:>14.3e} {:>14.3e}  {result}",
                    outcome.name, report.worst_position, report.worst_tangent,
                );
            }
        }
    }
    let all_pass = outcomes.iter().all(|o| o.passes());
    println!(
        "verdict: {}",
        if all_pass {
            "this adapter conforms"
        } else {
            "this adapter does NOT conform"
        }
    );
    Ok(all_pass)
}
