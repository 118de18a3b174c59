//! GPU-vs-CPU conformance: suites of surfaces and of curves that exercise every feature of
//! the evaluators, and the comparison of a mesh or polylines from any backend against the f64
//! reference, with the bars the GPU path promises.

use crate::error::{Error, Result};
use crate::geom::patches::{self, CoonsPatch};
use crate::geom::{
    BSplineCurve, BSplineSurface, Interval, KnotVector, bezier_curve, bezier_surface, curves,
    shapes,
};
use crate::gpu::{CoonsInputs, CurveInputs, GpuBatch, GpuContext, KernelInputs, ViewBatch};
use crate::mesh::{Mesh, Polyline, TessOptions, Tolerance};
use crate::plan::SurfacePlan;
use crate::plan::view::{MAX_VIEW_DEGREE, View, ViewOptions, ViewPlan};
use crate::{CpuTessellator, Tessellator};
use glam::camera::rh::{proj::directx::perspective, view::look_at_mat4};
use glam::{DVec2, DVec3};
use std::f64::consts::{FRAC_PI_2, PI};
use std::path::Path;

/// Position bar, relative to the surface's bounding-box diagonal.
pub const POSITION_REL_BAR: f64 = 1e-5;
/// Extra position allowance relative to the point's distance from the world origin: the f32
/// rounding of the surface origin and of the result (2 × 2⁻²⁴).
pub const F32_ROUNDING: f64 = 1.0 / 8_388_608.0;
/// Normal bar at regular points, in radians.
pub const NORMAL_BAR: f64 = 1e-4;
/// Normal bar near degenerate points (collapsed edges, poles), in radians.
pub const DEGENERATE_NORMAL_BAR: f64 = 1e-2;
/// uv bar (uv is in [0, 1]²): a few f32 units in the last place of 1.
pub const UV_BAR: f64 = 4.0 * f32::EPSILON as f64;
/// A vertex is regular when |S_u × S_v| ≥ this × (size / parameter width)²; closer to a
/// degenerate point the f32 cross product loses digits and the looser bar applies.
pub const REGULAR_REL: f64 = 1e-3;

/// Tangent bar: the error of C′ relative to the curve's scale of C′, the larger of
/// (control extent / parameter width) and the largest |C′| of the reference polyline.
pub const TANGENT_REL_BAR: f64 = 1e-5;

/// Cubic knots with a triple and a double interior knot (C⁰ and C¹ joints).
const CREASED_CUBIC_KNOTS: [f64; 13] = [
    0.0, 0.0, 0.0, 0.0, 0.3, 0.3, 0.3, 0.6, 0.6, 1.0, 1.0, 1.0, 1.0,
];
/// Cubic knots with two interior spans 1e-6 wide.
const TINY_SPAN_CUBIC_KNOTS: [f64; 11] = [
    0.0,
    0.0,
    0.0,
    0.0,
    0.5,
    0.5 + 1e-6,
    0.5 + 2e-6,
    1.0,
    1.0,
    1.0,
    1.0,
];

/// One case: surfaces and the grid to tessellate them on.
pub struct Case {
    pub name: String,
    pub surfaces: Vec<BSplineSurface>,
    pub options: TessOptions,
}

/// What a comparison measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Report {
    /// Largest position error minus the f32 rounding allowance, over the surface's diagonal.
    pub worst_position: f64,
    /// Largest normal angle at regular vertices (radians).
    pub worst_normal: f64,
    /// Largest normal angle near degenerate points (radians; 0 if there are none).
    pub worst_degenerate_normal: f64,
    /// Largest difference of a uv coordinate.
    pub worst_uv: f64,
    /// Vertices compared, and how many of them were near a degenerate point.
    pub vertices: usize,
    pub degenerate_vertices: usize,
    /// Index buffers identical and the layout the same.
    pub topology_equal: bool,
}

impl Report {
    pub fn passes(&self) -> bool {
        self.topology_equal
            && self.worst_position <= POSITION_REL_BAR
            && self.worst_normal <= NORMAL_BAR
            && self.worst_degenerate_normal <= DEGENERATE_NORMAL_BAR
            && self.worst_uv <= UV_BAR
    }
}

fn angle(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length().atan2(a.dot(b))
}

/// Compares `mesh` (from any backend) with the f64 reference for `surfaces`, all on the grid
/// of `options`.
pub fn compare(surfaces: &[BSplineSurface], options: &TessOptions, mesh: &Mesh) -> Result<Report> {
    compare_each(surfaces, &vec![*options; surfaces.len()], mesh)
}

/// As [`compare`], surface k on the grid of `options[k]`.
pub fn compare_each(
    surfaces: &[BSplineSurface],
    options: &[TessOptions],
    mesh: &Mesh,
) -> Result<Report> {
    let mut reference = Mesh::default();
    CpuTessellator.tessellate_each_into(surfaces, options, &mut reference)?;
    Ok(compare_surfaces(surfaces, &reference, mesh))
}

/// Runs both executors on one plan of `surfaces` (surface k on the grid of `options[k]`) —
/// the f64 CPU executor and a GPU batch on `context` — and compares them vertex for vertex.
pub fn compare_executors(
    context: &GpuContext,
    surfaces: &[BSplineSurface],
    options: &[TessOptions],
) -> Result<Report> {
    let plan = SurfacePlan::new(surfaces, options)?;
    let mut reference = Mesh::default();
    crate::cpu::execute_surfaces(&plan, surfaces, &mut reference)?;
    let batch = GpuBatch::from_plan(context, &plan, surfaces)?;
    batch.dispatch()?;
    Ok(compare_surfaces(surfaces, &reference, &batch.read_mesh()?))
}

/// Compares `mesh` with the f64 `reference` of `surfaces`.
fn compare_surfaces(surfaces: &[BSplineSurface], reference: &Mesh, mesh: &Mesh) -> Report {
    let measure = surface_measure(surfaces);
    compare_with_reference(reference, mesh, |part, _, uv| measure(part, uv))
}

/// For uv of surface k: the size of surface k (its control box diagonal) and whether the
/// point is regular (|S_u × S_v| ≥ [`REGULAR_REL`] × its cross scale).
fn surface_measure(surfaces: &[BSplineSurface]) -> impl Fn(usize, DVec2) -> (f64, bool) + '_ {
    |k, uv| {
        let surface = &surfaces[k];
        let sample = surface.evaluate(surface.range_u().lerp(uv.x), surface.range_v().lerp(uv.y));
        let cross = sample.du.cross(sample.dv).length();
        (
            surface.control_box_diagonal(),
            cross >= REGULAR_REL * surface.cross_scale(),
        )
    }
}

/// One view-dependent case: surfaces and the view the GPU re-plans them for.
pub struct ViewCase {
    pub name: String,
    pub surfaces: Vec<BSplineSurface>,
    pub view: View,
}

/// Surface cases of [`suite`] seen by a camera 2.5 diagonals away at half a pixel on an
/// 800 × 600 viewport: rational with extreme weights, poles, creases and tiny spans, far
/// from the origin, high degree (≤ [`MAX_VIEW_DEGREE`]), second-order corners.
pub fn view_suite() -> Vec<ViewCase> {
    let wanted = [
        "bicubic, weights 0.01..100",
        "sphere: poles (collapsed edges)",
        "repeated interior knots (C0 creases)",
        "tiny knot spans (1e-6)",
        "offset 1e5 from the origin",
        "rational, high degree, unclamped × clamped",
        "second-order corners (collapsed edge, zero-slope neighbour)",
    ];
    suite()
        .into_iter()
        .filter(|case| wanted.contains(&case.name.as_str()))
        .map(|case| {
            let surfaces: Vec<BSplineSurface> = case
                .surfaces
                .into_iter()
                .filter(|s| s.degree_u().max(s.degree_v()) <= MAX_VIEW_DEGREE)
                .collect();
            let (low, high) = surfaces.iter().map(BSplineSurface::control_box).fold(
                (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
                |(low, high), (a, b)| (low.min(a), high.max(b)),
            );
            let (centre, diagonal) = (0.5 * (low + high), (high - low).length());
            let eye = centre + DVec3::new(1.0, -1.5, 1.2).normalize() * 2.5 * diagonal;
            let near_far = ((0.1 * diagonal) as f32, (10.0 * diagonal) as f32);
            let view_projection = perspective(0.8, 4.0 / 3.0, near_far.0, near_far.1)
                * look_at_mat4(eye.as_vec3(), centre.as_vec3(), glam::Vec3::Z);
            ViewCase {
                name: format!("view: {}", case.name),
                surfaces,
                view: View {
                    view_projection,
                    viewport: glam::Vec2::new(800.0, 600.0),
                    tolerance_px: 0.5,
                },
            }
        })
        .collect()
}

/// Re-plans `surfaces` for `view` on the GPU ([`crate::gpu::ViewBatch`]) and compares the
/// frame with the f64 executor of the same plan at the rates the GPU chose: the rates must
/// each meet the view's tolerance and be the fewest (checked in f64), the triangles be the
/// same, and the vertices within the bars.
pub fn compare_view(
    context: &GpuContext,
    surfaces: &[BSplineSurface],
    view: &View,
) -> Result<Report> {
    let plan = ViewPlan::new(surfaces, ViewOptions::default())?;
    let batch = ViewBatch::new(context, &plan)?;
    batch.dispatch(view)?;
    let frame = batch.read_frame()?;
    let rates_valid = frame.rates.iter().enumerate().all(|(c, &rate)| {
        let (meets, fewest) = plan.rate_meets(c, rate, view, 1e-4);
        fewest && (meets || !rate.met)
    });
    let reference = crate::cpu::execute_view(&plan, surfaces, &frame.rates)?;
    let mesh = Mesh {
        positions: frame
            .vertices
            .iter()
            .map(|v| DVec3::from(v.position.map(f64::from)))
            .collect(),
        normals: frame
            .vertices
            .iter()
            .map(|v| DVec3::from(v.normal.map(f64::from)))
            .collect(),
        uvs: frame
            .vertices
            .iter()
            .map(|v| DVec2::from(v.uv.map(f64::from)))
            .collect(),
        indices: frame.indices,
        parts: reference.parts.clone(),
        polylines: Vec::new(),
    };
    // Each vertex is measured on the surface of the cell that evaluates it.
    let layout = plan.layout(&frame.rates);
    let cells: Vec<u32> = plan
        .vertex_samples(&frame.rates, &layout)
        .into_iter()
        .map(|(cell, _, _)| cell)
        .collect();
    let measure = surface_measure(surfaces);
    let mut report = compare_with_reference(&reference, &mesh, |_, k, uv| {
        measure(plan.cells[cells[k] as usize].surface as usize, uv)
    });
    report.topology_equal &= rates_valid;
    Ok(report)
}

/// As [`surface_measure`] for directly evaluated Coons patches (size: [`CoonsPatch::size`]).
fn coons_measure(patches: &[CoonsPatch]) -> impl Fn(usize, DVec2) -> (f64, bool) + '_ {
    |part, uv| {
        let sample = patches[part].evaluate(uv.x, uv.y);
        let cross = sample.du.cross(sample.dv).length();
        (
            patches[part].size(),
            cross >= REGULAR_REL * patches[part].cross_scale(),
        )
    }
}

/// Compares `mesh` (from any backend) with the f64 reference for directly evaluated Coons
/// patches, patch k on the grid of `options[k]`.
pub fn compare_coons(
    patches: &[CoonsPatch],
    options: &[TessOptions],
    mesh: &Mesh,
) -> Result<Report> {
    let mut reference = Mesh::default();
    CpuTessellator.tessellate_coons_into(patches, options, &mut reference)?;
    let measure = coons_measure(patches);
    Ok(compare_with_reference(&reference, mesh, |part, _, uv| {
        measure(part, uv)
    }))
}

/// Compares `mesh` with `reference` vertex by vertex; `measure(part, vertex, uv)` gives the
/// size of what the vertex of that part lies on and whether the point at `uv` is regular
/// (away from degenerate points).
fn compare_with_reference(
    reference: &Mesh,
    mesh: &Mesh,
    measure: impl Fn(usize, usize, DVec2) -> (f64, bool),
) -> Report {
    let mut report = Report {
        worst_position: 0.0,
        worst_normal: 0.0,
        worst_degenerate_normal: 0.0,
        worst_uv: 0.0,
        vertices: reference.vertex_count(),
        degenerate_vertices: 0,
        topology_equal: reference.indices == mesh.indices
            && reference.parts == mesh.parts
            && reference.vertex_count() == mesh.vertex_count(),
    };
    if reference.vertex_count() != mesh.vertex_count() {
        report.worst_position = f64::INFINITY;
        return report;
    }
    for (index, part) in reference.parts.iter().enumerate() {
        for k in part.first_vertex as usize..(part.first_vertex + part.vertex_count) as usize {
            let (size, regular) = measure(index, k, reference.uvs[k]);
            let expected = reference.positions[k];
            let error = (mesh.positions[k] - expected).length() - F32_ROUNDING * expected.length();
            report.worst_position = report.worst_position.max(error.max(0.0) / size);
            let normal_error = angle(mesh.normals[k], reference.normals[k]);
            if regular {
                report.worst_normal = report.worst_normal.max(normal_error);
            } else {
                report.degenerate_vertices += 1;
                report.worst_degenerate_normal = report.worst_degenerate_normal.max(normal_error);
            }
            if !normal_error.is_finite() || !mesh.positions[k].is_finite() {
                report.worst_normal = f64::INFINITY;
            }
            let uv_error = (mesh.uvs[k] - reference.uvs[k]).abs().max_element();
            // `max` would skip a NaN: a non-finite uv is the worst uv error.
            report.worst_uv = report.worst_uv.max(if uv_error.is_finite() {
                uv_error
            } else {
                f64::INFINITY
            });
        }
    }
    report
}

/// Writes the surface, curve and Coons suites' kernel inputs and f64 expectations to `dir`,
/// for running tessellate.wgsl, curves.wgsl and coons.wgsl on another WebGPU implementation
/// (tests/webgpu runs them in Chromium's): the three WGSL files as the crate compiles them, `manifest.json`
/// (entry points, bars, and per case its name, counts, chunk bindings and file names), per
/// surface case the binary inputs (`caseK.pieces`, `.tiles`, `.points`, `.tables`,
/// `.uniforms`) and expectations — `caseK.expected` holds per vertex 10 little-endian f64:
/// position relative to its surface's origin (3), unit normal (3), uv (2), 1 if regular else
/// 0, the surface's diagonal; `caseK.indices` the f64 path's triangles (u32) — and per curve
/// case each chunk's inputs (`curvesK.C.jobs`, `.points`, `.tables`) and `curvesK.expected`:
/// per sample 8 f64, position relative to its curve's origin (3), C′ (3), the curve's control
/// extent and its scale of C′ — and per Coons case each chunk's boundary-curve inputs
/// (`coonsK.C.boundary_jobs`, `.boundary_points`, `.boundary_tables`) and patch inputs
/// (`.jobs`, `.blends`), with `coonsK.expected` and `coonsK.indices` as for surfaces (the
/// patch's size in place of the diagonal). Returns the number of cases.
pub fn export_suite(dir: &Path) -> Result<usize> {
    let io = |path: &Path, source| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    std::fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
    let write = |name: &str, bytes: &[u8]| {
        let path = dir.join(name);
        std::fs::write(&path, bytes).map_err(|e| io(&path, e))
    };
    write("tessellate.wgsl", crate::gpu::TESSELLATE_WGSL.as_bytes())?;
    write("view.wgsl", crate::gpu::view::VIEW_WGSL.as_bytes())?;
    write("points.wgsl", crate::gpu::POINTS_WGSL.as_bytes())?;
    let mut cases_json = Vec::new();
    let cases = suite();
    // Cases sampled to a tolerance run the same kernels on cell grids; their triangles and
    // shared vertices come from the plan, not the kernels, so the export leaves them out.
    let grid_cases = cases.iter().filter(|case| case.options.tolerance.is_none());
    for (index, case) in grid_cases.enumerate() {
        let options = vec![case.options; case.surfaces.len()];
        let plan = SurfacePlan::new(&case.surfaces, &options)?;
        let inputs = KernelInputs::new(&plan, &case.surfaces)?;
        let mut reference = Mesh::default();
        crate::cpu::execute_surfaces(&plan, &case.surfaces, &mut reference)?;
        let expected =
            expected_vertices(&reference, &inputs.origins, surface_measure(&case.surfaces));
        let file = |what: &str| format!("case{index}.{what}");
        write(&file("pieces"), &inputs.pieces)?;
        write(&file("tiles"), &inputs.tiles)?;
        write(&file("points"), &inputs.points)?;
        write(&file("tables"), &inputs.tables)?;
        write(&file("uniforms"), &inputs.uniforms)?;
        write(&file("expected"), &expected)?;
        write(&file("indices"), bytemuck::cast_slice(&reference.indices))?;
        let chunks: Vec<String> = inputs
            .chunks
            .iter()
            .map(|chunk| {
                format!(
                    "{{\"passes\": {:?}, \"bindings\": {:?}}}",
                    chunk.passes.map(|(first, count)| [first, count]),
                    chunk.bindings.map(|(offset, size)| [offset, size])
                )
            })
            .collect();
        cases_json.push(format!(
            "{{\"name\": {:?}, \"prefix\": {:?}, \"vertices\": {}, \"indices\": {}, \"scratch_bytes\": {}, \"chunks\": [{}]}}",
            case.name,
            format!("case{index}"),
            inputs.vertex_count,
            inputs.index_count,
            inputs.scratch_bytes,
            chunks.join(", ")
        ));
    }
    write("curves.wgsl", crate::gpu::CURVES_WGSL.as_bytes())?;
    let mut curve_cases_json = Vec::new();
    let curve_cases = curve_suite();
    for (index, case) in curve_cases.iter().enumerate() {
        let samples = vec![case.samples; case.curves.len()];
        let plan = crate::plan::CurvePlan::new(&case.curves, &samples)?;
        let inputs = CurveInputs::new(&plan, &case.curves)?;
        let reference = CpuTessellator.tessellate_curves(&case.curves, &samples)?;
        let mut expected = Vec::new();
        for ((curve, polyline), origin) in case.curves.iter().zip(&reference).zip(&inputs.origins) {
            let size = curve.control_extent();
            let tangent_scale = polyline
                .tangents
                .iter()
                .fold(size / curve.range().width(), |m, t| m.max(t.length()));
            for (position, tangent) in polyline.positions.iter().zip(&polyline.tangents) {
                let values = (*position - *origin)
                    .to_array()
                    .into_iter()
                    .chain(tangent.to_array())
                    .chain([size, tangent_scale]);
                for value in values {
                    expected.extend_from_slice(&value.to_le_bytes());
                }
            }
        }
        let prefix = format!("curves{index}");
        write(&format!("{prefix}.expected"), &expected)?;
        let mut chunks = Vec::new();
        for (chunk_index, chunk) in inputs.chunks.iter().enumerate() {
            for (what, bytes) in [
                ("jobs", &chunk.jobs),
                ("points", &chunk.points),
                ("tables", &chunk.tables),
            ] {
                write(&format!("{prefix}.{chunk_index}.{what}"), bytes)?;
            }
            chunks.push(chunk.samples.to_string());
        }
        curve_cases_json.push(format!(
            "{{\"name\": {:?}, \"prefix\": {:?}, \"chunk_samples\": [{}]}}",
            case.name,
            prefix,
            chunks.join(", ")
        ));
    }
    write("coons.wgsl", crate::gpu::COONS_WGSL.as_bytes())?;
    let mut coons_cases_json = Vec::new();
    let coons_cases = coons_suite();
    for (index, case) in coons_cases.iter().enumerate() {
        let options = vec![case.options; case.patches.len()];
        let plan = crate::plan::CoonsPlan::new(&case.patches, &options)?;
        let inputs = CoonsInputs::new(&plan, &case.patches)?;
        let mut reference = Mesh::default();
        CpuTessellator.tessellate_coons_into(&case.patches, &options, &mut reference)?;
        let expected = expected_vertices(&reference, &inputs.origins, coons_measure(&case.patches));
        let prefix = format!("coons{index}");
        write(&format!("{prefix}.expected"), &expected)?;
        write(
            &format!("{prefix}.indices"),
            bytemuck::cast_slice(&reference.indices),
        )?;
        let mut chunks = Vec::new();
        for (chunk_index, chunk) in inputs.chunks.iter().enumerate() {
            let boundaries = &chunk.boundaries;
            for (what, bytes) in [
                ("boundary_jobs", &boundaries.jobs),
                ("boundary_points", &boundaries.points),
                ("boundary_tables", &boundaries.tables),
                ("jobs", &chunk.jobs),
                ("blends", &chunk.blends),
            ] {
                write(&format!("{prefix}.{chunk_index}.{what}"), bytes)?;
            }
            chunks.push(format!(
                "{{\"boundary_samples\": {}, \"vertices\": {}, \"indices\": {}}}",
                boundaries.samples, chunk.vertices, chunk.indices
            ));
        }
        coons_cases_json.push(format!(
            "{{\"name\": {:?}, \"prefix\": {:?}, \"chunks\": [{}]}}",
            case.name,
            prefix,
            chunks.join(", ")
        ));
    }
    let manifest = format!(
        "{{\"entry_points\": {:?}, \"uniform_stride\": {}, \"vertex_bytes\": {}, \"bars\": {{\"position_rel\": {:e}, \"f32_rounding\": {:e}, \"normal\": {:e}, \"degenerate_normal\": {:e}, \"uv\": {:e}, \"tangent_rel\": {:e}}}, \"cases\": [\n{}\n], \"curve_entry_point\": {:?}, \"sample_bytes\": {}, \"curve_cases\": [\n{}\n], \"coons_entry_point\": {:?}, \"coons_cases\": [\n{}\n], \"view_entry_points\": {:?}, \"points_entry_point\": {:?}}}\n",
        KernelInputs::ENTRY_POINTS,
        KernelInputs::UNIFORM_STRIDE,
        KernelInputs::VERTEX_BYTES,
        POSITION_REL_BAR,
        F32_ROUNDING,
        NORMAL_BAR,
        DEGENERATE_NORMAL_BAR,
        UV_BAR,
        TANGENT_REL_BAR,
        cases_json.join(",\n"),
        CurveInputs::ENTRY_POINT,
        CurveInputs::SAMPLE_BYTES,
        curve_cases_json.join(",\n"),
        CoonsInputs::ENTRY_POINT,
        coons_cases_json.join(",\n"),
        crate::gpu::view::ENTRY_POINTS,
        crate::gpu::points::ENTRY_POINT
    );
    write("manifest.json", manifest.as_bytes())?;
    Ok(cases_json.len() + curve_cases.len() + coons_cases.len())
}

/// The exported expectations of a mesh (see [`export_suite`]): per vertex 10 little-endian
/// f64 — position relative to its part's origin in `origins`, unit normal, uv, 1 if regular
/// else 0, the part's size — with `measure` as in [`compare_with_reference`].
fn expected_vertices(
    reference: &Mesh,
    origins: &[DVec3],
    measure: impl Fn(usize, DVec2) -> (f64, bool),
) -> Vec<u8> {
    let mut expected = Vec::with_capacity(reference.vertex_count() * 80);
    for (item, part) in reference.parts.iter().enumerate() {
        let first = part.first_vertex as usize;
        for k in first..first + part.vertex_count as usize {
            let (size, regular) = measure(item, reference.uvs[k]);
            let values = (reference.positions[k] - origins[item])
                .to_array()
                .into_iter()
                .chain(reference.normals[k].to_array())
                .chain(reference.uvs[k].to_array())
                .chain([f64::from(u8::from(regular)), size]);
            for value in values {
                expected.extend_from_slice(&value.to_le_bytes());
            }
        }
    }
    expected
}

/// One curve case: curves and the samples per curve.
pub struct CurveCase {
    pub name: String,
    pub curves: Vec<BSplineCurve>,
    pub samples: u32,
}

/// What a comparison of polylines measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurveReport {
    /// Largest position error minus the f32 rounding allowance, over the curve's control
    /// extent.
    pub worst_position: f64,
    /// Largest tangent (C′) error over the curve's scale of C′ (see [`TANGENT_REL_BAR`]).
    pub worst_tangent: f64,
    /// Samples compared.
    pub samples: usize,
    /// As many polylines and samples per polyline as the reference.
    pub layout_equal: bool,
}

impl CurveReport {
    pub fn passes(&self) -> bool {
        self.layout_equal
            && self.worst_position <= POSITION_REL_BAR
            && self.worst_tangent <= TANGENT_REL_BAR
    }
}

/// One case of the whole suite and what it measured.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub name: String,
    pub measured: Measured,
}

/// A surface case's report (grid, view-dependent or Coons) or a curve case's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Measured {
    Surface(Report),
    Curve(CurveReport),
}

impl Outcome {
    pub fn passes(&self) -> bool {
        match &self.measured {
            Measured::Surface(report) => report.passes(),
            Measured::Curve(report) => report.passes(),
        }
    }
}

/// Runs every case — [`suite`], [`view_suite`], [`coons_suite`] and [`curve_suite`] — on
/// `gpu`'s adapter against the f64 reference, in that order.
pub fn run_all(gpu: &crate::GpuTessellator) -> Result<Vec<Outcome>> {
    let mut outcomes = Vec::new();
    let mut push = |name: String, measured| outcomes.push(Outcome { name, measured });
    for case in suite() {
        // Both executors run one plan; compared vertex for vertex.
        let options = vec![case.options; case.surfaces.len()];
        let report = compare_executors(gpu.context(), &case.surfaces, &options)?;
        push(case.name, Measured::Surface(report));
    }
    for case in view_suite() {
        let report = compare_view(gpu.context(), &case.surfaces, &case.view)?;
        push(case.name, Measured::Surface(report));
    }
    for case in coons_suite() {
        let options = vec![case.options; case.patches.len()];
        let mut mesh = Mesh::default();
        gpu.tessellate_coons_into(&case.patches, &options, &mut mesh)?;
        let report = compare_coons(&case.patches, &options, &mesh)?;
        push(case.name, Measured::Surface(report));
    }
    for case in curve_suite() {
        let samples = vec![case.samples; case.curves.len()];
        let polylines = gpu.tessellate_curves(&case.curves, &samples)?;
        let report = compare_curves(&case.curves, &samples, &polylines)?;
        push(case.name, Measured::Curve(report));
    }
    Ok(outcomes)
}

/// Compares `polylines` (from any backend) with the f64 reference for `curves`, curve k
/// sampled `samples[k]` times.
pub fn compare_curves(
    curves: &[BSplineCurve],
    samples: &[u32],
    polylines: &[Polyline],
) -> Result<CurveReport> {
    let reference = CpuTessellator.tessellate_curves(curves, samples)?;
    let layout_equal = reference.len() == polylines.len()
        && reference.iter().zip(polylines).all(|(r, p)| {
            r.positions.len() == p.positions.len() && r.tangents.len() == p.tangents.len()
        });
    let mut report = CurveReport {
        worst_position: 0.0,
        worst_tangent: 0.0,
        samples: reference.iter().map(|r| r.positions.len()).sum(),
        layout_equal,
    };
    if !layout_equal {
        report.worst_position = f64::INFINITY;
        return Ok(report);
    }
    for ((curve, expected), found) in curves.iter().zip(&reference).zip(polylines) {
        let size = curve.control_extent();
        let tangent_scale = expected
            .tangents
            .iter()
            .fold(size / curve.range().width(), |m, t| m.max(t.length()));
        for k in 0..expected.positions.len() {
            let p = expected.positions[k];
            let error = (found.positions[k] - p).length() - F32_ROUNDING * p.length();
            report.worst_position = report.worst_position.max(error.max(0.0) / size);
            let tangent_error = (found.tangents[k] - expected.tangents[k]).length();
            report.worst_tangent = report.worst_tangent.max(tangent_error / tangent_scale);
            if !(found.positions[k].is_finite() && found.tangents[k].is_finite()) {
                report.worst_position = f64::INFINITY;
            }
        }
    }
    Ok(report)
}

/// A net of `nu × nv` points on a wavy sheet spanning `size`, deterministic.
fn wavy_net(nu: usize, nv: usize, size: f64) -> Vec<DVec3> {
    (0..nu * nv)
        .map(|k| {
            let (i, j) = ((k % nu) as f64, (k / nu) as f64);
            let z =
                (0.7 * i).sin() * (0.4 * j + 0.3).cos() + 0.25 * ((k * 7919) % 17) as f64 / 17.0;
            DVec3::new(
                i / (nu - 1).max(1) as f64,
                j / (nv - 1).max(1) as f64,
                0.3 * z,
            ) * size
        })
        .collect()
}

/// Weights spread over [lo, hi] (geometrically), deterministic.
fn spread_weights(n: usize, lo: f64, hi: f64) -> Vec<f64> {
    (0..n)
        .map(|k| lo * (hi / lo).powf(((k * 37) % 101) as f64 / 100.0))
        .collect()
}

fn surface(
    ku: KnotVector,
    kv: KnotVector,
    points: &[DVec3],
    weights: Option<&[f64]>,
) -> BSplineSurface {
    BSplineSurface::try_new(ku, kv, points, weights).expect("conformance surfaces are valid")
}

/// The conformance suite: degrees 1..=20 in both directions, rational and not, clamped,
/// unclamped and periodic knots, repeated interior knots, tiny spans, sub-ranges, large
/// offsets and scales, weights from 0.01 to 100, collapsed edges and poles; then the
/// degeneracy cross product (placements to 1e7 × scales 1e-3..1e4 × poles, collapsed
/// edges, corners, creases, tiny spans × weights to 1e-3..1e3 × low and high degree).
pub fn suite() -> Vec<Case> {
    // Non-square grids, so that a u/v swap anywhere cannot pass.
    let grid = |n: u32| TessOptions::DEFAULT.with_grid(n, n * 3 / 4 + 1);
    let mut cases = Vec::new();
    // Every degree in u and in v: (d, 21 − d).
    let degrees = (1..=20)
        .map(|d| {
            let (p, q) = (d, 21 - d);
            let (nu, nv) = (p + 2, q + 1);
            surface(
                KnotVector::clamped_uniform(p, nu).unwrap(),
                KnotVector::clamped_uniform(q, nv).unwrap(),
                &wavy_net(nu, nv, 2.0),
                None,
            )
        })
        .collect();
    cases.push(Case {
        name: "degrees 1..=20 (u) × 20..=1 (v), clamped".into(),
        surfaces: degrees,
        options: grid(17),
    });
    let rational_high: Vec<BSplineSurface> = (1..=20)
        .step_by(3)
        .map(|d| {
            let (nu, nv) = (d + 3, 21 - d + 2);
            let ku = KnotVector::uniform(d, nu).unwrap();
            let kv = KnotVector::clamped_uniform(21 - d, nv).unwrap();
            surface(
                ku,
                kv,
                &wavy_net(nu, nv, 5.0),
                Some(&spread_weights(nu * nv, 0.2, 5.0)),
            )
        })
        .collect();
    cases.push(Case {
        name: "adaptive: rational, high degree, tolerance 1e-2 of the size".into(),
        surfaces: rational_high.clone(),
        options: TessOptions::DEFAULT.with_tolerance(Tolerance::Relative(1e-2)),
    });
    cases.push(Case {
        name: "rational, high degree, unclamped × clamped".into(),
        surfaces: rational_high,
        options: grid(19),
    });
    let (nu, nv) = (12, 9);
    let bicubic = |weights: Option<&[f64]>| {
        surface(
            KnotVector::clamped_uniform(3, nu).unwrap(),
            KnotVector::clamped_uniform(3, nv).unwrap(),
            &wavy_net(nu, nv, 10.0),
            weights,
        )
    };
    cases.push(Case {
        name: "bicubic, non-rational".into(),
        surfaces: vec![bicubic(None)],
        options: grid(64),
    });
    cases.push(Case {
        name: "bicubic, weights 0.01..100".into(),
        surfaces: vec![bicubic(Some(&spread_weights(nu * nv, 0.01, 100.0)))],
        options: grid(64),
    });
    // Sampled to a tolerance: cells of different rates, joined by the plan's triangles.
    cases.push(Case {
        name: "adaptive: bicubic, weights 0.01..100, tolerance 1e-3 of the size".into(),
        surfaces: vec![bicubic(Some(&spread_weights(nu * nv, 0.01, 100.0)))],
        options: TessOptions::DEFAULT.with_tolerance(Tolerance::Relative(1e-3)),
    });
    // Periodic: uniform knots with the first `degree` columns repeated at the end.
    let periodic = {
        let n = 10;
        let ring: Vec<DVec3> = (0..n)
            .map(|k| (std::f64::consts::TAU * k as f64 / n as f64).sin_cos())
            .map(|(s, c)| DVec3::new(c, s, 0.0))
            .collect();
        let mut points = Vec::new();
        for j in 0..5 {
            for i in 0..n + 3 {
                points.push(ring[i % n] * (1.0 + 0.1 * j as f64) + DVec3::Z * j as f64);
            }
        }
        let ku = KnotVector::uniform(3, n + 3).unwrap();
        let kv = KnotVector::clamped_uniform(3, 5).unwrap();
        surface(
            ku,
            kv,
            &points,
            Some(&spread_weights(points.len(), 0.5, 2.0)),
        )
    };
    cases.push(Case {
        name: "periodic (unclamped uniform, wrapped net)".into(),
        surfaces: vec![periodic],
        options: grid(48),
    });
    let repeated = {
        let ku = KnotVector::try_new(3, CREASED_CUBIC_KNOTS.to_vec()).unwrap();
        let kv = KnotVector::try_new(2, vec![0.0, 0.0, 0.0, 0.5, 0.5, 1.0, 1.0, 1.0]).unwrap();
        surface(
            ku,
            kv,
            &wavy_net(9, 5, 3.0),
            Some(&spread_weights(45, 0.3, 3.0)),
        )
    };
    cases.push(Case {
        name: "repeated interior knots (C0 creases)".into(),
        surfaces: vec![repeated],
        options: grid(41),
    });
    let tiny = {
        let ku = KnotVector::try_new(3, TINY_SPAN_CUBIC_KNOTS.to_vec()).unwrap();
        let kv = KnotVector::try_new(2, vec![0.0, 0.0, 0.0, 1e-5, 1.0, 1.0, 1.0]).unwrap();
        surface(ku, kv, &wavy_net(7, 4, 4.0), None)
    };
    cases.push(Case {
        name: "tiny knot spans (1e-6)".into(),
        surfaces: vec![tiny],
        options: grid(33),
    });
    let sub_range = bicubic(None)
        .with_range(Interval::new(0.13, 0.71), Interval::new(0.4, 0.45))
        .unwrap();
    cases.push(Case {
        name: "sub-range of the knot domain".into(),
        surfaces: vec![sub_range],
        options: grid(30),
    });
    let offset = |shift: DVec3, scale: f64| {
        let points: Vec<DVec3> = wavy_net(nu, nv, scale)
            .into_iter()
            .map(|p| p + shift)
            .collect();
        surface(
            KnotVector::clamped_uniform(3, nu).unwrap(),
            KnotVector::clamped_uniform(3, nv).unwrap(),
            &points,
            Some(&spread_weights(nu * nv, 0.5, 2.0)),
        )
    };
    cases.push(Case {
        name: "offset 1e5 from the origin".into(),
        surfaces: vec![offset(DVec3::new(1e5, -2e5, 3e4), 10.0)],
        options: grid(40),
    });
    cases.push(Case {
        name: "scale 1e-3 and 1e4".into(),
        surfaces: vec![offset(DVec3::ZERO, 1e-3), offset(DVec3::splat(5e4), 1e4)],
        options: grid(40),
    });
    cases.push(Case {
        name: "sphere: poles (collapsed edges)".into(),
        surfaces: vec![shapes::sphere(DVec3::new(3.0, -1.0, 2.0), 2.0)],
        options: grid(33),
    });
    let pinched = {
        // A bicubic patch whose whole v = 0 row collapses to one point, like the teapot's lid.
        let mut points = wavy_net(4, 4, 1.0);
        for p in &mut points[..4] {
            *p = DVec3::new(0.5, 0.0, 0.1);
        }
        bezier_surface(3, 3, &points, None).unwrap()
    };
    cases.push(Case {
        name: "collapsed edge (pinched bicubic)".into(),
        surfaces: vec![pinched],
        options: grid(25),
    });
    cases.push(Case {
        name: "classic forms (Coons, ruled, Hermite, quadrics)".into(),
        surfaces: classic_forms(),
        options: grid(21),
    });
    cases.push(Case {
        name: "second-order corners (collapsed edge, zero-slope neighbour)".into(),
        surfaces: second_order_corners(),
        options: grid(33),
    });
    cases.push(Case {
        name: "adaptive: second-order corners, tolerance 1e-3 of the size".into(),
        surfaces: second_order_corners(),
        options: TessOptions::DEFAULT.with_tolerance(Tolerance::Relative(1e-3)),
    });
    cases.extend(cross_product_cases(grid(11)));
    cases
}

/// The boundaries S(u,0), S(u,1), S(0,v), S(1,v) of a curved fan: u = 0 collapses to a point
/// and the spokes and rim leave the plane. With the cubic blend, on the rows next to the pole
/// S_v is (1 − α(u))·S(1, v)′ plus terms as small — the GPU's blend table carries 1 − α
/// (formed in f32 it would keep the cubic's 1.8e-4 at u = 1/128 only to 1.6e-4 of itself) —
/// and at the corners on the pole α′ = 0 makes the first-order limit vanish: the normal there
/// takes third derivatives.
fn curved_fan() -> [BSplineCurve; 4] {
    let cubic = |points: [DVec3; 4]| bezier_curve(3, &points, None).unwrap();
    let spoke = |to: DVec3, lift: f64| {
        cubic([
            DVec3::ZERO,
            to / 3.0 + DVec3::new(0.0, 0.0, lift),
            2.0 * to / 3.0 + DVec3::new(0.0, 0.0, 0.5 * lift),
            to,
        ])
    };
    let point = bezier_curve(1, &[DVec3::ZERO, DVec3::ZERO], None).unwrap();
    let (x, y) = (DVec3::new(2.0, 0.0, 0.3), DVec3::new(0.0, 2.0, -0.2));
    let rim = cubic([
        x,
        x + DVec3::new(0.2, 1.0, 0.6),
        y + DVec3::new(1.0, 0.3, -0.5),
        y,
    ]);
    [spoke(x, 0.8), spoke(y, -0.6), point, rim]
}

/// Surfaces with second-order degenerate corners, where S_u × S_v and the first-order term
/// of its expansion both vanish, so the limit normal takes third derivatives (the GPU's
/// kernels take the host's there): a bicubic patch whose v = 0 row collapses to a pole and
/// whose next row leaves the pole's corner radially, and the curved fan's Coons patch with
/// the cubic blend converted exactly (degree 6 × 3: the general path).
pub fn second_order_corners() -> Vec<BSplineSurface> {
    let pole = DVec3::ZERO;
    let next = [
        DVec3::new(1.0, 0.0, 0.25),
        DVec3::new(1.5, 0.0, 0.375),
        DVec3::new(1.0, 1.5, 0.5),
        DVec3::new(0.5, 2.0, 0.0),
    ];
    let far = [
        DVec3::new(-0.5, 1.0, 0.75),
        DVec3::new(1.0, 2.0, 1.0),
        DVec3::new(2.0, 2.5, 0.5),
        DVec3::new(1.0, 3.0, -0.25),
        DVec3::new(-1.0, 2.0, 1.0),
        DVec3::new(0.5, 3.0, 1.25),
        DVec3::new(1.5, 3.5, 0.75),
        DVec3::new(0.75, 4.0, 0.0),
    ];
    let points: Vec<DVec3> = std::iter::repeat_n(pole, 4)
        .chain(next)
        .chain(far)
        .collect();
    let [v0, v1, u0, u1] = curved_fan();
    let fan = patches::coons(
        patches::CoonsBoundaries {
            v0: &v0,
            v1: &v1,
            u0: &u0,
            u1: &u1,
        },
        &patches::Blend::Cubic,
        1e-12,
    )
    .unwrap();
    vec![bezier_surface(3, 3, &points, None).unwrap(), fan]
}

/// The name every case of the degeneracy cross product starts with.
pub const CROSS_PRODUCT: &str = "degeneracies";

/// The degeneracy cross product, one case per placement and scale: {near, 1e5 and 1e7 from
/// the origin} × {scale 1e-3, 1, 1e4}, each with every feature {pole, collapsed edge, corner
/// where a collapsed edge meets a crease, crease, 1e-6 span} × {polynomial, rational with
/// weights 1e-3..1e3} × {degree ≤ 3, > 3}: 20 surfaces per case, 180 in all.
fn cross_product_cases(options: TessOptions) -> Vec<Case> {
    let placements = [
        ("at the origin", DVec3::ZERO),
        ("1e5 from the origin", DVec3::new(1e5, -7e4, 3e4)),
        ("1e7 from the origin", DVec3::new(1e7, -4e6, 2e6)),
    ];
    let mut cases = Vec::new();
    for (where_, offset) in placements {
        for scale in [1e-3, 1.0, 1e4] {
            let mut surfaces = Vec::new();
            for feature in Feature::ALL {
                for (p, q) in [(2, 3), (5, 4)] {
                    let (knots_u, knots_v, net) = feature.net(p, q);
                    let points: Vec<DVec3> = net.iter().map(|&x| x * scale + offset).collect();
                    for weights in [None, Some(spread_weights(points.len(), 1e-3, 1e3))] {
                        surfaces.push(surface(
                            knots_u.clone(),
                            knots_v.clone(),
                            &points,
                            weights.as_deref(),
                        ));
                    }
                }
            }
            cases.push(Case {
                name: format!("{CROSS_PRODUCT} {where_}, scale {scale:e}"),
                surfaces,
                options,
            });
        }
    }
    cases
}

/// The degenerate and non-smooth features of the cross product.
#[derive(Clone, Copy)]
enum Feature {
    /// A dome whose v = 0 row collapses to its apex: the limit normal is the same all
    /// along it.
    Pole,
    /// A wavy net whose v = 0 row collapses to one point: the limit normal turns along it.
    CollapsedEdge,
    /// A collapsed v = 0 row meeting a C⁰ crease along u (an interior knot of multiplicity
    /// p, the net kinked there).
    Corner,
    /// The C⁰ crease alone.
    Crease,
    /// Two interior knots 1e-6 apart along u.
    TinySpan,
}

impl Feature {
    const ALL: [Feature; 5] = [
        Feature::Pole,
        Feature::CollapsedEdge,
        Feature::Corner,
        Feature::Crease,
        Feature::TinySpan,
    ];

    /// Knots along u and v and a unit-sized net (u fastest) of degrees (p, q).
    fn net(self, p: usize, q: usize) -> (KnotVector, KnotVector, Vec<DVec3>) {
        let clamped = |interior: &[f64]| {
            let mut knots = vec![0.0; p + 1];
            knots.extend_from_slice(interior);
            knots.extend(std::iter::repeat_n(1.0, p + 1));
            KnotVector::try_new(p, knots).expect("valid knots")
        };
        let knots_u = match self {
            Feature::Pole | Feature::CollapsedEdge => clamped(&[0.5]),
            Feature::Corner | Feature::Crease => clamped(&vec![0.5; p]),
            Feature::TinySpan => clamped(&[0.5, 0.5 + 1e-6]),
        };
        let nv = q + 3;
        let knots_v = KnotVector::clamped_uniform(q, nv).expect("valid knots");
        let nu = knots_u.control_count();
        let mut net = wavy_net(nu, nv, 1.0);
        match self {
            Feature::Pole => {
                for (k, point) in net.iter_mut().enumerate() {
                    let (i, j) = (k % nu, k / nu);
                    let angle = PI * i as f64 / (nu - 1) as f64;
                    let r = j as f64 / (nv - 1) as f64;
                    *point = DVec3::new(r * angle.cos(), r * angle.sin(), 0.5 * (1.0 - r * r));
                }
            }
            Feature::CollapsedEdge | Feature::Corner => {
                for point in &mut net[..nu] {
                    *point = DVec3::new(0.5, -0.1, 0.2);
                }
            }
            Feature::Crease | Feature::TinySpan => {}
        }
        if matches!(self, Feature::Corner | Feature::Crease) {
            // The column at the crease rises: the two sides meet at an angle.
            for j in usize::from(matches!(self, Feature::Corner))..nv {
                net[j * nu + p].z += 0.4;
            }
        }
        (knots_u, knots_v, net)
    }
}

/// One surface of each classic form whose conversion raises degrees or weights: a cubic-blend
/// Coons patch of circular arcs (rational, degree 7), a ruled surface between a cubic and an
/// arc, a Hermite patch and the quadrics.
fn classic_forms() -> Vec<BSplineSurface> {
    use crate::geom::curves;
    use crate::geom::patches::{self, Blend, CoonsBoundaries, HermiteCorners};
    let quarter = Interval::new(0.0, FRAC_PI_2);
    let arc = |x: DVec3, y: DVec3, a: f64| {
        curves::arc(DVec3::ZERO, 1.0, x, y, Interval::new(a, a + FRAC_PI_2)).unwrap()
    };
    let (v0, u1) = (
        arc(DVec3::X, DVec3::Y, 0.0),
        arc(DVec3::X, DVec3::Y, FRAC_PI_2),
    );
    let (u0, v1) = (
        arc(DVec3::X, DVec3::Z, 0.0),
        arc(DVec3::X, DVec3::Z, FRAC_PI_2),
    );
    let boundaries = CoonsBoundaries {
        v0: &v0,
        v1: &v1,
        u0: &u0,
        u1: &u1,
    };
    let cubic = crate::geom::bezier_curve(
        3,
        &[
            DVec3::ZERO,
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(2.0, -1.0, 0.0),
            DVec3::X * 3.0,
        ],
        None,
    )
    .unwrap();
    let over = curves::arc(
        DVec3::new(1.5, 0.0, 2.0),
        1.5,
        -DVec3::X,
        DVec3::Y,
        Interval::new(0.0, PI),
    )
    .unwrap();
    let hermite = HermiteCorners {
        points: [
            DVec3::ZERO,
            DVec3::X * 2.0,
            DVec3::Y * 2.0,
            DVec3::new(2.0, 2.0, 1.0),
        ],
        du: [
            DVec3::new(2.0, 0.0, 1.0),
            DVec3::new(2.0, 0.0, -1.0),
            DVec3::X * 2.0,
            DVec3::X * 2.0,
        ],
        dv: [
            DVec3::Y * 2.0,
            DVec3::new(0.0, 2.0, 1.0),
            DVec3::Y * 2.0,
            DVec3::Y * 2.0,
        ],
        twists: [DVec3::ZERO, DVec3::ZERO, DVec3::ZERO, DVec3::Z],
    };
    let centre = DVec3::new(1.0, -2.0, 0.5);
    let [upper, lower] =
        shapes::hyperboloid_two_sheets(centre, DVec3::new(1.0, 2.0, 1.5), shapes::FULL_TURN, 4.0)
            .unwrap();
    vec![
        patches::coons(boundaries, &Blend::Cubic, 1e-12).unwrap(),
        patches::ruled(&cubic, &over).unwrap(),
        patches::hermite_patch(&hermite).unwrap(),
        shapes::ellipsoid(
            centre,
            DVec3::new(3.0, 2.0, 1.0),
            shapes::FULL_TURN,
            Interval::new(-1.0, FRAC_PI_2),
        )
        .unwrap(),
        shapes::torus_section(centre, 2.0, 0.5, Interval::new(0.0, PI), shapes::FULL_TURN).unwrap(),
        shapes::hyperboloid_one_sheet(
            centre,
            DVec3::new(1.0, 1.5, 2.0),
            shapes::FULL_TURN,
            Interval::new(-2.0, 3.0),
        )
        .unwrap(),
        upper,
        lower,
        shapes::elliptic_cylinder(centre, 1.0, 1.0, quarter, Interval::new(0.0, 2.0)).unwrap(),
        shapes::elliptic_paraboloid(
            centre,
            1.0,
            2.0,
            1.0,
            shapes::FULL_TURN,
            Interval::new(0.0, 1.5),
        )
        .unwrap(),
        shapes::hyperbolic_paraboloid(
            centre,
            1.0,
            1.0,
            2.0,
            Interval::new(-1.0, 1.0),
            Interval::new(-1.0, 2.0),
        )
        .unwrap(),
        shapes::elliptic_cone(
            centre,
            1.0,
            0.5,
            shapes::FULL_TURN,
            Interval::new(-1.0, 2.0),
        )
        .unwrap(),
    ]
}

/// The curve suite: every degree, rational weights over four decades, unclamped, repeated
/// and tiny knot spans, sub-ranges, large offsets, and the classic curves.
pub fn curve_suite() -> Vec<CurveCase> {
    let wavy = |n: usize, size: f64| -> Vec<DVec3> {
        wavy_net(n, 2, size)[..n]
            .iter()
            .enumerate()
            .map(|(k, p)| *p + DVec3::Y * size * (0.9 * k as f64).cos())
            .collect()
    };
    let clamped = |p: usize, points: &[DVec3], weights: Option<&[f64]>| {
        BSplineCurve::try_new(
            KnotVector::clamped_uniform(p, points.len()).unwrap(),
            points,
            weights,
        )
        .unwrap()
    };
    let mut cases = vec![CurveCase {
        name: "Bezier curves, degrees 1..=20".into(),
        curves: (1..=20)
            .map(|d| bezier_curve(d, &wavy(d + 1, 3.0), None).unwrap())
            .collect(),
        samples: 101,
    }];
    let points = wavy(14, 5.0);
    cases.push(CurveCase {
        name: "NURBS, degrees 2..=5, weights 0.01..100".into(),
        curves: (2..=5)
            .map(|d| clamped(d, &points, Some(&spread_weights(14, 0.01, 100.0))))
            .collect(),
        samples: 257,
    });
    let knotted = |degree, knots: Vec<f64>| {
        let knots = KnotVector::try_new(degree, knots).unwrap();
        let n = knots.control_count();
        BSplineCurve::try_new(knots, &wavy(n, 2.0), Some(&spread_weights(n, 0.3, 3.0))).unwrap()
    };
    cases.push(CurveCase {
        name: "unclamped, repeated and tiny spans, sub-range".into(),
        curves: vec![
            knotted(3, (0..14).map(f64::from).collect()),
            knotted(3, CREASED_CUBIC_KNOTS.to_vec()),
            knotted(3, TINY_SPAN_CUBIC_KNOTS.to_vec()),
            knotted(4, (0..16).map(f64::from).collect())
                .with_range(Interval::new(5.3, 9.1))
                .unwrap(),
        ],
        samples: 97,
    });
    let shifted = |shift: DVec3, scale: f64| {
        let points: Vec<DVec3> = wavy(9, scale).into_iter().map(|p| p + shift).collect();
        clamped(3, &points, Some(&spread_weights(9, 0.5, 2.0)))
    };
    cases.push(CurveCase {
        name: "offset 1e5, scales 1e-3 and 1e4".into(),
        curves: vec![
            shifted(DVec3::new(1e5, -2e5, 3e4), 10.0),
            shifted(DVec3::ZERO, 1e-3),
            shifted(DVec3::splat(5e4), 1e4),
        ],
        samples: 129,
    });
    let ring: Vec<DVec3> = (0..7)
        .map(|k| f64::from(k) * std::f64::consts::TAU / 7.0)
        .map(|a| DVec3::new(a.cos(), a.sin(), 0.2 * (3.0 * a).sin()))
        .collect();
    let tangents: Vec<DVec3> = ring.iter().map(|p| p.cross(DVec3::Z) * -2.0).collect();
    cases.push(CurveCase {
        name: "classic: arcs, periodic, natural, C-R, Hermite".into(),
        curves: vec![
            curves::arc(
                DVec3::new(2.0, 1.0, 0.0),
                1.5,
                DVec3::X,
                DVec3::Z,
                Interval::new(0.0, std::f64::consts::TAU),
            )
            .unwrap(),
            curves::arc(
                DVec3::ZERO,
                3.0,
                DVec3::Y,
                DVec3::X,
                Interval::new(PI, -0.25 * PI),
            )
            .unwrap(),
            curves::periodic_cubic(&ring, 0.4).unwrap(),
            curves::natural_cubic(&ring).unwrap(),
            curves::catmull_rom(&ring, &[0.5; 7]).unwrap(),
            curves::hermite(&ring, &tangents).unwrap(),
        ],
        samples: 200,
    });
    cases
}

/// Directly evaluated Coons patches and the grid to tessellate them on.
pub struct CoonsCase {
    pub name: String,
    pub patches: Vec<CoonsPatch>,
    pub options: TessOptions,
}

/// The Coons suite: non-polynomial blends (cosine, a rational function) over rational and
/// polynomial boundaries, a polynomial blend (also convertible exactly), a patch with a
/// collapsed boundary (degenerate normals) and one 1e5 from the origin.
pub fn coons_suite() -> Vec<CoonsCase> {
    use crate::geom::patches::{Blend, CoonsBoundaries, coons_patch};
    let arc = |centre: DVec3, x: DVec3, y: DVec3, a: f64, b: f64| {
        curves::arc(centre, 2.0, x, y, Interval::new(a, b)).unwrap()
    };
    let cubic = |points: [DVec3; 4]| bezier_curve(3, &points, None).unwrap();
    let make = |shift: DVec3, blend: Blend| {
        let o = shift;
        let v0 = arc(o, DVec3::X, DVec3::Y, 0.0, FRAC_PI_2);
        let v1 = cubic([
            o + DVec3::new(2.0, 0.0, 3.0),
            o + DVec3::new(2.5, 1.0, 3.5),
            o + DVec3::new(1.0, 2.5, 2.5),
            o + DVec3::new(0.0, 2.0, 3.0),
        ]);
        let u0 = cubic([
            o + DVec3::new(2.0, 0.0, 0.0),
            o + DVec3::new(3.0, 0.0, 1.0),
            o + DVec3::new(3.0, -0.5, 2.0),
            o + DVec3::new(2.0, 0.0, 3.0),
        ]);
        let u1 = cubic([
            o + DVec3::new(0.0, 2.0, 0.0),
            o + DVec3::new(0.5, 2.5, 1.0),
            o + DVec3::new(-0.5, 2.0, 2.0),
            o + DVec3::new(0.0, 2.0, 3.0),
        ]);
        let boundaries = CoonsBoundaries {
            v0: &v0,
            v1: &v1,
            u0: &u0,
            u1: &u1,
        };
        coons_patch(boundaries, blend, 1e-9 * (1.0 + shift.length())).unwrap()
    };
    let rational: fn(f64) -> [f64; 3] = |t| {
        // α = (1−t)² / ((1−t)² + t²), differentiated by the quotient rule.
        let (n, n1, n2) = ((1.0 - t) * (1.0 - t), -2.0 * (1.0 - t), 2.0);
        let (d, d1, d2) = (n + t * t, 4.0 * t - 2.0, 4.0);
        let a = n / d;
        let a1 = (n1 - a * d1) / d;
        let a2 = (n2 - 2.0 * a1 * d1 - a * d2) / d;
        [a, a1, a2]
    };
    // A quarter disc whose u = 0 boundary collapses to the centre.
    let fan = {
        let centre = DVec3::new(1.0, -1.0, 0.5);
        let spoke = |to: DVec3| bezier_curve(1, &[centre, centre + to], None).unwrap();
        let point = bezier_curve(1, &[centre, centre], None).unwrap();
        let rim = arc(centre, DVec3::X, DVec3::Y, 0.0, FRAC_PI_2);
        let boundaries = CoonsBoundaries {
            v0: &spoke(DVec3::X * 2.0),
            v1: &spoke(DVec3::Y * 2.0),
            u0: &point,
            u1: &rim,
        };
        coons_patch(boundaries, Blend::Cosine, 1e-12).unwrap()
    };
    // Boundaries that leave one corner in the same direction: S_u × S_v vanishes at (0, 0)
    // without a collapsed boundary, and the limit normal there takes the blend's α″ (at a
    // collapsed boundary it multiplies the difference of two equal points).
    let tangent_corner = {
        let v0 = cubic([
            DVec3::ZERO,
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(2.0, 0.3, 0.4),
            DVec3::new(3.0, 0.0, 0.0),
        ]);
        let u0 = cubic([
            DVec3::ZERO,
            DVec3::new(0.8, 0.0, 0.0),
            DVec3::new(1.0, 1.5, 0.5),
            DVec3::new(0.5, 3.0, 0.0),
        ]);
        let v1 = cubic([
            DVec3::new(0.5, 3.0, 0.0),
            DVec3::new(1.5, 3.5, 0.4),
            DVec3::new(2.5, 3.2, 0.1),
            DVec3::new(3.0, 3.0, 0.3),
        ]);
        let u1 = cubic([
            DVec3::new(3.0, 0.0, 0.0),
            DVec3::new(3.4, 1.0, 0.2),
            DVec3::new(3.2, 2.0, 0.5),
            DVec3::new(3.0, 3.0, 0.3),
        ]);
        let boundaries = CoonsBoundaries {
            v0: &v0,
            v1: &v1,
            u0: &u0,
            u1: &u1,
        };
        coons_patch(boundaries, Blend::Cosine, 1e-12).unwrap()
    };
    let curved_fan = {
        let [v0, v1, u0, u1] = curved_fan();
        let boundaries = CoonsBoundaries {
            v0: &v0,
            v1: &v1,
            u0: &u0,
            u1: &u1,
        };
        coons_patch(boundaries, Blend::Cubic, 1e-12).unwrap()
    };
    vec![
        CoonsCase {
            name: "Coons: curved fan, fine grid (cubic blend)".into(),
            patches: vec![curved_fan],
            options: TessOptions::DEFAULT.with_grid(129, 65),
        },
        CoonsCase {
            name: "Coons: tangent corner (cosine blend)".into(),
            patches: vec![tangent_corner],
            options: TessOptions::DEFAULT.with_grid(21, 17),
        },
        CoonsCase {
            name: "Coons: cosine, rational and cubic blends".into(),
            patches: vec![
                make(DVec3::ZERO, Blend::Cosine),
                make(DVec3::ZERO, Blend::Function(rational)),
                make(DVec3::ZERO, Blend::Cubic),
            ],
            options: TessOptions::DEFAULT.with_grid(37, 29),
        },
        CoonsCase {
            name: "Coons: collapsed boundary, offset 1e5".into(),
            patches: vec![fan, make(DVec3::new(1e5, -2e5, 3e4), Blend::Cosine)],
            options: TessOptions::DEFAULT.with_grid(33, 33),
        },
    ]
}
