// Grid tessellation of rational tensor-product B-spline surfaces, in f32.
//
// The host (src/gpu/pack.rs) splits every surface into pieces (bands of grid rows), computes
// basis values in f64 and uploads them with the control points, which are stored relative to
// the surface's own origin. One workgroup per tile of 64 work items; four passes, of which a
// piece takes one or two. Pieces of degree ≤ 3 along u (the Bezier-run path):
//   evaluate_bezier_runs — per run of vertices along a row inside one knot span along u: the
//                          net contracted along v at the row, turned into the span's cubic
//                          Bezier form (value, ∂v, ∂vv) by a host-computed matrix, with the
//                          value's forward differences, which keep ∂u exact in f32 over tiny
//                          spans; then each vertex a cubic in the span-local parameter, from
//                          registers (no per-vertex loads: what decides speed on SIMD-on-CPU
//                          implementations such as lavapipe, where every storage access is a
//                          loop over the lanes).
// Pieces of higher degree along u (the general path), from basis tables of every grid column:
//   contract_rows        — per grid row and control column: the control net contracted along
//                          v (value, ∂v, ∂vv; homogeneous);
//   evaluate_vertices    — per run of vertices along a row: contraction along u of p+1 of
//                          those.
// Both evaluations apply the quotient rule and compute the unit normal; where S_u × S_v
// vanishes, the limit normal from second derivatives, in a second loop over the run that only
// runs with such a vertex take. Position = origin + local point, added last. Then
//   connect_cells        — per grid cell: two counter-clockwise triangles.
// Only core WGSL and f32: it runs on WebGPU as well as native adapters.

// Mirrors src/gpu/pack.rs `Piece`: all scalars, 96 bytes.
struct Piece {
    origin_x: f32, origin_y: f32, origin_z: f32,
    // |S_u × S_v|² at or below this (model units² per parameter²) counts as degenerate.
    degenerate_sq: f32,
    // Widths of the evaluation range (parameter units): the approach direction of limits.
    width_u: f32, width_v: f32,
    count_u: u32, degree_u: u32, degree_v: u32,
    grid_u: u32, grid_v: u32,
    // The band of grid rows [first_row, first_row + rows) this piece covers, and the number
    // of cell rows it connects.
    first_row: u32, rows: u32, cell_rows: u32,
    // Global index of the band's first vertex and first index.
    first_vertex: u32, first_index: u32,
    // Offsets: control points (vec4 units), column and row tables (f32 units), contracted
    // scratch (vec4 units, relative to the chunk).
    points: u32, columns: u32, row_table: u32, contracted: u32,
    // Bezier-run path: knot spans along u touched by the grid ("segments", 0 on the general
    // path), column runs per row, and the offsets of their tables (f32 units).
    segments: u32, runs: u32, segment_table: u32, run_table: u32,
}

// Mirrors src/gpu/pack.rs `ChunkParams`: where this chunk's bound ranges begin, so that
// global offsets can be made binding-relative.
struct ChunkParams {
    tile_offset: u32, tile_count: u32,
    vertex_origin: u32, index_origin: u32,
    point_origin: u32, table_origin: u32,
    piece_origin: u32, pad: u32,
}

// One workgroup's work: items first_item .. first_item + 64 (clipped) of a piece.
struct Tile { piece: u32, first_item: u32 }

const TILE: u32 = 64u;
const MAX_ORDER: u32 = 21u;
// Per segment: [first control column (bits), 1 / knot-span width, M (7 × 4, row-major)]:
// Σ_c M[j][c] · (value of control column first + c) is the Bezier coefficient b_j (j < 4) or
// the forward difference b_{j−3} − b_{j−4} (j ≥ 4).
const SEGMENT_STRIDE: u32 = 30u;
// Per run: [first grid column, column count, segment (bits each), span-local parameter of the
// first column, local parameter step].
const RUN_STRIDE: u32 = 5u;

@group(0) @binding(0) var<uniform> chunk: ChunkParams;
@group(0) @binding(1) var<storage, read> pieces: array<Piece>;
@group(0) @binding(2) var<storage, read> tiles: array<Tile>;
@group(0) @binding(3) var<storage, read> points: array<vec4<f32>>;
// Per column (then per row) entry of a piece: [fraction, span (bits), N_0..N_p, N'_0..N'_p,
// N''_0..N''_p]: 2 + 3(p+1) floats.
@group(0) @binding(4) var<storage, read> tables: array<f32>;
@group(0) @binding(5) var<storage, read_write> contracted: array<vec4<f32>>;
// Two vec4 per vertex: (position xyz, normal x), (normal yz, uv).
@group(0) @binding(6) var<storage, read_write> vertices: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> indices: array<u32>;

// The piece (binding-relative) and item of this invocation (callers check the item against
// the piece).
fn work_item(wid: vec3<u32>, groups: vec3<u32>, lid: u32) -> vec2<u32> {
    let tile = tiles[chunk.tile_offset + wid.x + wid.y * groups.x];
    return vec2<u32>(tile.piece - chunk.piece_origin, tile.first_item + lid);
}

fn entry_stride(degree: u32) -> u32 {
    return 2u + 3u * (degree + 1u);
}

@compute @workgroup_size(64)
fn contract_rows(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
                 @builtin(local_invocation_index) lid: u32) {
    if (wid.x + wid.y * groups.x >= chunk.tile_count) { return; }
    let work = work_item(wid, groups, lid);
    let piece = pieces[work.x];
    let item = work.y;
    if (item >= piece.rows * piece.count_u) { return; }
    let row = item / piece.count_u;
    let column = item % piece.count_u;
    let q = piece.degree_v;
    let entry = piece.row_table + row * entry_stride(q) - chunk.table_origin;
    let span = bitcast<u32>(tables[entry + 1u]);
    var value = vec4<f32>(0.0);
    var dv = vec4<f32>(0.0);
    var dvv = vec4<f32>(0.0);
    for (var b = 0u; b <= q; b++) {
        let point = points[piece.points - chunk.point_origin + (span - q + b) * piece.count_u + column];
        value += tables[entry + 2u + b] * point;
        dv += tables[entry + 3u + q + b] * point;
        dvv += tables[entry + 4u + 2u * q + b] * point;
    }
    let out = piece.contracted + 3u * item;
    contracted[out] = value;
    contracted[out + 1u] = dv;
    contracted[out + 2u] = dvv;
}

// Writes the vertex whose first vec4 is `out`.
fn store_vertex(out: u32, position: vec3<f32>, normal: vec3<f32>, uv: vec2<f32>) {
    vertices[out] = vec4<f32>(position, normal.x);
    vertices[out + 1u] = vec4<f32>(normal.yz, uv);
}

// Vertices one invocation evaluates: a run along u of one grid row, sharing the row's data
// (fewer loads per vertex: what decides speed on SIMD-on-CPU implementations such as
// lavapipe, where every per-invocation load is a gather).
const RUN: u32 = 8u;

// A point of a rational surface: homogeneous A, A_u, A_v and, by the quotient rule, S, S_u,
// S_v (relative to the surface origin).
struct Frame {
    a: vec4<f32>, au: vec4<f32>, av: vec4<f32>,
    s: vec3<f32>, su: vec3<f32>, sv: vec3<f32>,
}

fn frame_from(a: vec4<f32>, au: vec4<f32>, av: vec4<f32>) -> Frame {
    let s = a.xyz / a.w;
    return Frame(a, au, av, s, (au.xyz - au.w * s) / a.w, (av.xyz - av.w * s) / a.w);
}

// Whether S_u × S_v is too short to give the normal (then the limit normal applies).
fn is_degenerate(piece: Piece, normal: vec3<f32>) -> bool {
    return dot(normal, normal) <= piece.degenerate_sq;
}

// The general path's frame at the grid column whose table entry starts at `column`, from the
// row's contracted control columns starting at `base`.
fn general_frame(p: u32, column: u32, base: u32) -> Frame {
    var a = vec4<f32>(0.0);
    var au = vec4<f32>(0.0);
    var av = vec4<f32>(0.0);
    for (var k = 0u; k <= p; k++) {
        let t = contracted[base + 3u * k];
        let t_v = contracted[base + 3u * k + 1u];
        let n = tables[column + 2u + k];
        a += n * t;
        au += tables[column + 3u + p + k] * t;
        av += n * t_v;
    }
    return frame_from(a, au, av);
}

@compute @workgroup_size(64)
fn evaluate_vertices(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
                     @builtin(local_invocation_index) lid: u32) {
    if (wid.x + wid.y * groups.x >= chunk.tile_count) { return; }
    let work = work_item(wid, groups, lid);
    let piece = pieces[work.x];
    let runs_per_row = (piece.grid_u + RUN - 1u) / RUN;
    let item = work.y;
    if (item >= piece.rows * runs_per_row) { return; }
    let row = item / runs_per_row;
    let first = (item % runs_per_row) * RUN;
    let last = min(first + RUN, piece.grid_u);
    let p = piece.degree_u;
    let stride = entry_stride(p);
    let row_base = piece.contracted + 3u * row * piece.count_u;
    let origin = vec3<f32>(piece.origin_x, piece.origin_y, piece.origin_z);
    let row_out = piece.first_vertex + row * piece.grid_u - chunk.vertex_origin;
    let v_fraction = tables[piece.row_table + row * entry_stride(piece.degree_v) - chunk.table_origin];
    var degenerate = false;
    for (var i = first; i < last; i++) {
        let column = piece.columns + i * stride - chunk.table_origin;
        let span = bitcast<u32>(tables[column + 1u]);
        let frame = general_frame(p, column, row_base + 3u * (span - p));
        let normal = cross(frame.su, frame.sv);
        degenerate = degenerate | is_degenerate(piece, normal);
        let uv = vec2<f32>(tables[column], v_fraction);
        store_vertex(2u * (row_out + i), frame.s + origin, normalize(normal), uv);
    }
    // The run's vertices at degenerate points, again, with the limit normal: a second loop
    // rather than a branch in the first, because SIMD-on-CPU adapters (lavapipe) execute a
    // branch that no lane takes but leave a loop once no lane runs it.
    let redo_last = select(first, last, degenerate);
    for (var i = first; i < redo_last; i++) {
        let column = piece.columns + i * stride - chunk.table_origin;
        let span = bitcast<u32>(tables[column + 1u]);
        let base = row_base + 3u * (span - p);
        let frame = general_frame(p, column, base);
        if (is_degenerate(piece, cross(frame.su, frame.sv))) {
            let uv = vec2<f32>(tables[column], v_fraction);
            let normal = limit_normal(piece, column, base, frame, uv);
            store_vertex(2u * (row_out + i), frame.s + origin, normalize(normal), uv);
        }
    }
}

// The limit normal where S_u × S_v vanishes (see grid_common.wgsl), from the second
// derivatives of the row's contracted control columns starting at `base`; `uv` is the grid
// fraction.
fn limit_normal(piece: Piece, column: u32, base: u32, frame: Frame, uv: vec2<f32>) -> vec3<f32> {
    let p = piece.degree_u;
    var auu = vec4<f32>(0.0);
    var auv = vec4<f32>(0.0);
    var avv = vec4<f32>(0.0);
    for (var k = 0u; k <= p; k++) {
        let t = contracted[base + 3u * k];
        let t_v = contracted[base + 3u * k + 1u];
        let t_vv = contracted[base + 3u * k + 2u];
        auu += tables[column + 4u + 2u * p + k] * t;
        auv += tables[column + 3u + p + k] * t_v;
        avv += tables[column + 2u + k] * t_vv;
    }
    return limit_normal_from(piece, frame, auu, auv, avv, uv);
}

// The limit normal from the homogeneous second derivatives; `uv` is the grid fraction.
fn limit_normal_from(piece: Piece, frame: Frame, auu: vec4<f32>, auv: vec4<f32>, avv: vec4<f32>,
                     uv: vec2<f32>) -> vec3<f32> {
    let w = frame.a.w;
    let s = frame.s;
    let su = frame.su;
    let sv = frame.sv;
    let suu = (auu.xyz - 2.0 * frame.au.w * su - auu.w * s) / w;
    let suv = (auv.xyz - frame.au.w * sv - frame.av.w * su - auv.w * s) / w;
    let svv = (avv.xyz - 2.0 * frame.av.w * sv - avv.w * s) / w;
    return first_order_limit_normal(su, sv, suu, suv, svv, vec2<f32>(piece.width_u, piece.width_v),
                                    uv, piece.degenerate_sq);
}

@compute @workgroup_size(64)
fn evaluate_bezier_runs(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
                        @builtin(local_invocation_index) lid: u32) {
    if (wid.x + wid.y * groups.x >= chunk.tile_count) { return; }
    let work = work_item(wid, groups, lid);
    let piece = pieces[work.x];
    let item = work.y;
    if (item >= piece.rows * piece.runs) { return; }
    // Run-major: neighbouring invocations (the SIMD lanes of a CPU adapter) take the same run
    // of neighbouring rows, so their loops have the same length even where spans differ.
    let row = item % piece.rows;
    let run = piece.run_table + (item / piece.rows) * RUN_STRIDE - chunk.table_origin;
    let first = bitcast<u32>(tables[run]);
    let count = bitcast<u32>(tables[run + 1u]);
    let segment = piece.segment_table + bitcast<u32>(tables[run + 2u]) * SEGMENT_STRIDE - chunk.table_origin;
    let t0 = tables[run + 3u];
    let dt = tables[run + 4u];
    let inv_width = tables[segment + 1u];
    // The net contracted along v at this row (value, ∂v, ∂vv; columns: the segment's four
    // control columns, those past the degree repeating the last one, whose matrix entries
    // are zero).
    let q = piece.degree_v;
    let entry = piece.row_table + row * entry_stride(q) - chunk.table_origin;
    let span = bitcast<u32>(tables[entry + 1u]);
    let net = piece.points - chunk.point_origin + (span - q) * piece.count_u + bitcast<u32>(tables[segment]);
    let last = piece.degree_u;
    var value = mat4x4<f32>();
    var value_v = mat4x4<f32>();
    var value_vv = mat4x4<f32>();
    for (var k = 0u; k <= q; k++) {
        let at = net + k * piece.count_u;
        let p = mat4x4<f32>(points[at], points[at + min(1u, last)], points[at + min(2u, last)], points[at + last]);
        value += tables[entry + 2u + k] * p;
        value_v += tables[entry + 3u + q + k] * p;
        value_vv += tables[entry + 4u + 2u * q + k] * p;
    }
    // The span's cubic Bezier form: coefficients of the value, their forward differences,
    // coefficients of ∂v.
    let m0 = matrix_row(segment, 0u);
    let m1 = matrix_row(segment, 1u);
    let m2 = matrix_row(segment, 2u);
    let m3 = matrix_row(segment, 3u);
    let b = mat4x4<f32>(value * m0, value * m1, value * m2, value * m3);
    let f = mat3x4<f32>(value * matrix_row(segment, 4u), value * matrix_row(segment, 5u),
                        value * matrix_row(segment, 6u));
    let d = mat4x4<f32>(value_v * m0, value_v * m1, value_v * m2, value_v * m3);
    let origin = vec3<f32>(piece.origin_x, piece.origin_y, piece.origin_z);
    let row_out = piece.first_vertex + row * piece.grid_u - chunk.vertex_origin;
    let v_fraction = tables[entry];
    let u_scale = 1.0 / f32(piece.grid_u - 1u);
    var degenerate = false;
    for (var step = 0u; step < count; step++) {
        let frame = bezier_frame(b, f, d, inv_width, t0 + f32(step) * dt);
        let normal = cross(frame.su, frame.sv);
        degenerate = degenerate | is_degenerate(piece, normal);
        let uv = vec2<f32>(f32(first + step) * u_scale, v_fraction);
        store_vertex(2u * (row_out + first + step), frame.s + origin, normalize(normal), uv);
    }
    // The run's vertices at degenerate points, again, with the limit normal (a second loop:
    // see evaluate_vertices).
    let e = mat4x4<f32>(value_vv * m0, value_vv * m1, value_vv * m2, value_vv * m3);
    let redo = select(0u, count, degenerate);
    for (var step = 0u; step < redo; step++) {
        let t = t0 + f32(step) * dt;
        let frame = bezier_frame(b, f, d, inv_width, t);
        if (is_degenerate(piece, cross(frame.su, frame.sv))) {
            let s1 = 1.0 - t;
            // ∂uu from the second differences, ∂uv from the differences of ∂v's coefficients.
            let auu = f * vec3<f32>(-s1, s1 - t, t) * (6.0 * inv_width * inv_width);
            let wt = bernstein3_derivative(t);
            let auv = d * vec4<f32>(-wt.x, wt.x - wt.y, wt.y - wt.z, wt.z) * inv_width;
            let avv = e * bernstein3(t);
            let uv = vec2<f32>(f32(first + step) * u_scale, v_fraction);
            let normal = limit_normal_from(piece, frame, auu, auv, avv, uv);
            store_vertex(2u * (row_out + first + step), frame.s + origin, normalize(normal), uv);
        }
    }
}

// Row `j` of the 7 × 4 matrix of the segment entry at `segment`.
fn matrix_row(segment: u32, j: u32) -> vec4<f32> {
    let at = segment + 2u + 4u * j;
    return vec4<f32>(tables[at], tables[at + 1u], tables[at + 2u], tables[at + 3u]);
}

// Cubic Bernstein weights at t.
fn bernstein3(t: f32) -> vec4<f32> {
    let s1 = 1.0 - t;
    return vec4<f32>(s1 * s1 * s1, 3.0 * t * s1 * s1, 3.0 * t * t * s1, t * t * t);
}

// Weights of a cubic's forward differences in its t-derivative: 3 B²_j(t).
fn bernstein3_derivative(t: f32) -> vec3<f32> {
    let s1 = 1.0 - t;
    return vec3<f32>(3.0 * s1 * s1, 6.0 * t * s1, 3.0 * t * t);
}

// The Bezier-run path's frame at span-local t from the span's coefficients: value `b`, its
// forward differences `f` (∂u = 3 Σ B²_j(t) f_j / width) and ∂v `d`.
fn bezier_frame(b: mat4x4<f32>, f: mat3x4<f32>, d: mat4x4<f32>, inv_width: f32, t: f32) -> Frame {
    let w = bernstein3(t);
    return frame_from(b * w, f * bernstein3_derivative(t) * inv_width, d * w);
}

@compute @workgroup_size(64)
fn connect_cells(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
                 @builtin(local_invocation_index) lid: u32) {
    if (wid.x + wid.y * groups.x >= chunk.tile_count) { return; }
    let work = work_item(wid, groups, lid);
    let piece = pieces[work.x];
    let item = work.y;
    let cells_per_row = piece.grid_u - 1u;
    if (item >= piece.cell_rows * cells_per_row) { return; }
    let row = item / cells_per_row;
    let i = item % cells_per_row;
    let triangles = cell_triangles(piece.first_vertex + row * piece.grid_u + i, piece.grid_u);
    let out = piece.first_index + 6u * item - chunk.index_origin;
    for (var k = 0u; k < 6u; k++) {
        indices[out + k] = triangles[k];
    }
}
