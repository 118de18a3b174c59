//! The one error type of the library. Every variant names what is wrong and where.

use std::path::PathBuf;

/// Result alias used throughout knotwork.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong in knotwork, from bad geometry to a missing GPU.
///
/// Geometry errors carry the index (knot, control point, weight) that is at fault; file errors
/// wrap them with the line ([`Error::AtLine`]) and the path ([`Error::InFile`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    #[error("degree {degree} is outside the supported range 1..={max}")]
    DegreeOutOfRange { degree: usize, max: usize },
    #[error("knot {index} is not finite ({value})")]
    KnotNotFinite { index: usize, value: f64 },
    #[error("knots decrease at index {index} ({previous} > {value})")]
    KnotsDecreasing {
        index: usize,
        previous: f64,
        value: f64,
    },
    #[error(
        "knot {value} at index {index} has multiplicity {multiplicity}, more than the {max} allowed there"
    )]
    KnotMultiplicity {
        index: usize,
        value: f64,
        multiplicity: usize,
        max: usize,
    },
    #[error("{found} knots for degree {degree}: at least {min} are needed (2 × (degree + 1))")]
    TooFewKnots {
        found: usize,
        degree: usize,
        min: usize,
    },
    #[error("the knot domain [{start}, {end}] is empty")]
    EmptyDomain { start: f64, end: f64 },
    #[error("{found} control points given, {expected} expected ({what})")]
    ControlPointCount {
        expected: usize,
        found: usize,
        what: &'static str,
    },
    #[error("control point {index} is not finite")]
    ControlPointNotFinite { index: usize },
    #[error("weight {index} is {value}: weights must be finite and > 0")]
    InvalidWeight { index: usize, value: f64 },
    #[error(
        "parameter range [{start}, {end}] is not inside the domain [{domain_start}, {domain_end}] or is empty"
    )]
    RangeOutsideDomain {
        start: f64,
        end: f64,
        domain_start: f64,
        domain_end: f64,
    },
    #[error("{name} is {value}: it must be finite and > 0")]
    InvalidParameter { name: &'static str, value: f64 },
    #[error("breakpoints must increase strictly: breakpoint {index} is {value}")]
    BreakpointsNotIncreasing { index: usize, value: f64 },
    #[error("{found} points given for {form}: at least {min} are needed")]
    TooFewPoints {
        found: usize,
        min: usize,
        form: &'static str,
    },
    #[error("{name} = {value} lies outside [{start}, {end}]")]
    ParameterOutside {
        name: &'static str,
        value: f64,
        start: f64,
        end: f64,
    },
    #[error("the curves do not meet at {at}: they are {gap} apart")]
    CurvesDoNotMeet { at: String, gap: f64 },
    #[error("joint {joint} is not C{required} continuous (measured: {measured})")]
    ContinuityNotMet {
        joint: usize,
        required: u8,
        measured: String,
    },
    #[error(
        "the blend is not a polynomial: the Coons patch has no exact B-spline form (tessellate it as a CoonsPatch)"
    )]
    BlendNotPolynomial,
    #[error("a blending function must be 1 at 0 and 0 at 1; this one is {at_zero} and {at_one}")]
    InvalidBlend { at_zero: f64, at_one: f64 },
    #[error("{format} files cannot hold curves (polylines): write .obj or .glb")]
    PolylinesUnsupported { format: &'static str },
    #[error("grid {nu}x{nv} is invalid: each side needs at least 2 samples")]
    GridTooSmall { nu: u32, nv: u32 },
    #[error("tolerance {value:e} is invalid: it must be a finite number greater than 0")]
    InvalidTolerance { value: f64 },
    #[error(
        "tolerance {tolerance:e} (longest edge {max_edge:e}, angle {max_angle_degrees}°) needs more than {segments} segments across one knot span: ask for a larger tolerance, edge or angle"
    )]
    ToleranceTooFine {
        tolerance: f64,
        max_edge: f64,
        /// Degrees (infinite: no angle limit).
        max_angle_degrees: f64,
        segments: u32,
    },
    #[error("longest edge {value:e} is invalid: it must be a finite number greater than 0")]
    InvalidMaxEdge { value: f64 },
    #[error(
        "angle {degrees:e}° is invalid: it must be a number of degrees greater than 0 and below 180"
    )]
    InvalidMaxAngle { degrees: f64 },
    #[error("seam {seam} {reason}")]
    InvalidSeam { seam: usize, reason: String },
    #[error(
        "seam {seam}: its sides are {gap:e} apart at the same fraction of their ranges (at most {allowed:e} allowed): they are not one curve, run either way, at the same parameters"
    )]
    SeamGap { seam: usize, gap: f64, allowed: f64 },
    #[error(
        "{what} cannot be sampled to a tolerance yet: give them a grid (JSON \"grid\", --grid or grid=)"
    )]
    NoToleranceFor { what: &'static str },
    #[error(
        "view-dependent options: {cells_per_span} cells per knot span (1..=16 allowed) and at most {max_segments} segments per cell (1..=256 allowed)"
    )]
    InvalidViewOptions {
        cells_per_span: u32,
        max_segments: u32,
    },
    #[error("{found} sets of tessellation options for {expected} surfaces")]
    OptionsCount { expected: usize, found: usize },
    #[error("{found} sample counts for {expected} curves")]
    SampleCounts { expected: usize, found: usize },
    #[error("trim loop {loop_index} {problem}")]
    InvalidTrimLoop { loop_index: usize, problem: String },
    /// A special curve or point of a face (OBJ `scrv`, `sp`): `what` is "curve" or "point".
    #[error("special {what} {index} {problem}")]
    InvalidSpecial {
        what: &'static str,
        index: usize,
        problem: String,
    },
    #[error(
        "the trimmed face needs more than {vertices} vertices for tolerance {tolerance:e}: ask for a larger tolerance"
    )]
    TrimmedTooFine { vertices: usize, tolerance: f64 },
    #[error("not supported: {what}")]
    Unsupported { what: String },
    #[error("entity {kind} (directory entry {directory}): {source}")]
    InEntity {
        kind: u32,
        directory: usize,
        source: Box<Error>,
    },
    #[error("STEP entity #{id} ({kind}) {problem}")]
    StepEntity {
        id: u64,
        kind: String,
        problem: String,
    },
    #[error("STEP entity #{id} ({kind}): {source}")]
    InStepEntity {
        id: u64,
        kind: String,
        source: Box<Error>,
    },
    #[error("scene node {node} {problem}")]
    InvalidSceneNode { node: usize, problem: String },
    #[error("invalid B-rep: {what}")]
    InvalidBrep { what: String },
    #[error("item {index} ({name}): {source}")]
    InItem {
        index: usize,
        name: String,
        source: Box<Error>,
    },
    #[error("surface {index}: {source}")]
    InSurface { index: usize, source: Box<Error> },
    #[error("curve {index}: {source}")]
    InCurve { index: usize, source: Box<Error> },
    #[error("a buffer holds {found} elements where {expected} are needed")]
    BufferLength { expected: usize, found: usize },
    #[error(
        "the mesh would have {vertices} vertices and {indices} triangle indices; u32 indices allow at most 4294967295 of each"
    )]
    MeshTooLarge { vertices: u64, indices: u64 },
    #[error(
        "the mesh would take {needed} bytes of memory, over the budget of {budget} (--max-memory, or max_memory= from Python): use a coarser grid or a larger budget"
    )]
    OverMemoryBudget { needed: u64, budget: u64 },
    #[error(
        "{}: the mesh file would take {needed} bytes, and the disk has {available} free: use a coarser grid or another disk",
        path.display()
    )]
    NoRoomOnDisk {
        path: PathBuf,
        needed: u64,
        available: u64,
    },
    #[error(
        "the mesh would have {needed} triangles, over the budget of {budget} (--max-triangles, or max_triangles= from Python): ask for a larger tolerance or budget, or leave the tolerance out to have it chosen"
    )]
    OverTriangleBudget { needed: u64, budget: u64 },
    #[error(
        "a budget of {budget} triangles is below the {least} the scene takes at its coarsest (one segment per knot span, grids as given): raise --max-triangles (max_triangles= from Python)"
    )]
    TriangleBudgetTooSmall { budget: u64, least: u64 },
    #[error("{message}")]
    Syntax { message: String },
    #[error(
        "vertex reference {reference} is out of range: {available} vertices are defined above it"
    )]
    VertexReference { reference: i64, available: usize },
    #[error("the file ended early: {expected}")]
    UnexpectedEnd { expected: String },
    #[error("unknown file format for {path:?}: expected one of {expected}")]
    UnknownFormat {
        path: PathBuf,
        expected: &'static str,
    },
    #[error("the plan was made for {planned} items, but {given} were given to execute it")]
    PlanMismatch { planned: usize, given: usize },
    #[error("{what} need knotwork's `{feature}` feature, which this build leaves out")]
    FeatureDisabled {
        feature: &'static str,
        what: &'static str,
    },
    #[error("no GPU adapter: {reason}")]
    NoAdapter { reason: String },
    #[error("{}: no surface file ({expected}) in this directory", path.display())]
    NoInputFiles {
        path: PathBuf,
        expected: &'static str,
    },
    #[error(
        "{}: the mesh would be written over this input: give another output",
        path.display()
    )]
    OutputIsInput { path: PathBuf },
    #[error(
        "{} and {} would both be written to {}: rename one, or tessellate them separately",
        first.display(), second.display(), output.display()
    )]
    OutputCollision {
        output: PathBuf,
        first: PathBuf,
        second: PathBuf,
    },
    #[error(
        "{}: with several inputs the output is a folder, and this names a file (.{extension})",
        path.display()
    )]
    OutputNotAFolder { path: PathBuf, extension: String },
    #[error(
        "{}: the extension names {extension} but the format asked for is {format}; drop one or make them agree",
        path.display()
    )]
    FormatConflict {
        path: PathBuf,
        extension: &'static str,
        format: &'static str,
    },
    #[error("{what}: {problem}")]
    OutputTarget { what: &'static str, problem: String },
    #[error("GPU error: {message}")]
    Gpu { message: String },
    #[error(
        "the GPU job cannot fit: {what} needs {bytes} bytes, over the {limit}-byte limit it is planned within (the device's, or one given for the batch)"
    )]
    GpuJobTooLarge {
        what: &'static str,
        bytes: u64,
        limit: u64,
    },
    #[error(
        "surface {index} changed shape (degrees, control point counts, knots or range): upload a new batch"
    )]
    SurfaceShapeChanged { index: usize },
    #[error("{what} index {index} is out of range: the batch has {count}")]
    IndexOutOfRange {
        what: &'static str,
        index: usize,
        count: usize,
    },
    #[error("line {line}: {source}")]
    AtLine { line: usize, source: Box<Error> },
    #[error("{}: {source}", path.display())]
    InFile { path: PathBuf, source: Box<Error> },
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
}

impl Error {
    /// Wraps this error with the 1-based line of the file it was found on.
    pub fn at_line(self, line: usize) -> Error {
        Error::AtLine {
            line,
            source: Box::new(self),
        }
    }

    /// Wraps this error with the file it was found in.
    pub fn in_file(self, path: impl Into<PathBuf>) -> Error {
        Error::InFile {
            path: path.into(),
            source: Box::new(self),
        }
    }

    /// This error from working on the file at `path`, naming it unless it already does (read
    /// errors do; errors from tessellating what was read do not).
    pub fn naming_file(self, path: &std::path::Path) -> Error {
        if self.to_string().contains(&*path.to_string_lossy()) {
            self
        } else {
            self.in_file(path)
        }
    }

    pub(crate) fn syntax(message: impl Into<String>) -> Error {
        Error::Syntax {
            message: message.into(),
        }
    }

    /// The innermost error, past any line and file wrappers.
    pub fn root(&self) -> &Error {
        match self {
            Error::AtLine { source, .. }
            | Error::InFile { source, .. }
            | Error::InSurface { source, .. }
            | Error::InCurve { source, .. }
            | Error::InEntity { source, .. }
            | Error::InItem { source, .. } => source.root(),
            other => other,
        }
    }

    /// The 1-based line this error was reported on, if it came from a file.
    pub fn line(&self) -> Option<usize> {
        match self {
            Error::AtLine { line, .. } => Some(*line),
            Error::InFile { source, .. }
            | Error::InEntity { source, .. }
            | Error::InItem { source, .. } => source.line(),
            _ => None,
        }
    }
}
