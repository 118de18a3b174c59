// Grid tessellation of rational tensor-product B-spline surfaces, in f32.
//
// The host (src/gpu/surfaces.rs) splits every surface into pieces (bands of grid rows),
// computes basis values in f64 and uploads them with the control points: Cartesian, relative
// to the surface's own origin, with their weights, (P − origin, w). Every row of a piece is cut
// into runs of vertices inside one knot span along u, and each (row, run) sums its support
// relative to a reference control point R: the homogeneous points summed are ((P − R)·w, w).
// Where the weights of a span's support spread by more than a factor 16, runs are single
// vertices and R is the point with the largest basis value × weight there: its term is
// exactly zero, and the quotient rule (A_u − w_u·S)/w cancels only what the other points
// contribute — without it, a heavy weight pinning the surface near its point leaves S_u small
// while the cancelled terms stay as large as the model. Elsewhere runs are long (few loads
// per vertex) and R is the support's first point, which bounds that cancellation by the
// weights' ratio.
// One workgroup per tile of 64 work items; four passes, of which a piece takes one or two.
// Pieces of degree ≤ 3 along u (the Bezier-run path):
//   evaluate_bezier_runs — per (run, row): the net contracted along v at the row, turned into
//                          the span's cubic Bezier form (value, ∂v, ∂vv) by a host-computed
//                          matrix, with the value's forward differences, which keep ∂u exact in
//                          f32 over tiny spans; then each vertex a cubic in the span-local
//                          parameter, from registers (no per-vertex loads: what decides speed
//                          on SIMD-on-CPU implementations such as lavapipe, where every storage
//                          access is a loop over the lanes).
// Pieces of higher degree along u (the general path), from basis tables of every grid column:
//   contract_rows        — per (run, row): the p+1 control columns of the run's span
//                          contracted along v at the row (value, ∂v, ∂vv; homogeneous,
//                          relative to the reference, which is stored with them);
//   evaluate_vertices    — per (run, row): each vertex a contraction along u of those.
// Both evaluations apply the quotient rule and compute the unit normal; where S_u × S_v
// vanishes, the limit normal from second derivatives, in a second loop over the run that only
// runs with such a vertex take. Position = origin + reference + local point, added last. Then
//   connect_cells        — per grid cell: two counter-clockwise triangles.
// Only core WGSL and f32: it runs on WebGPU as well as native adapters.

// Mirrors src/gpu/surfaces.rs `Piece`: all scalars, 144 bytes.
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
    // Knot spans along u touched by the grid on the Bezier-run path ("segments", 0 on the
    // general path), column runs per row (both paths), and the offsets of their tables (f32
    // units).
    segments: u32, runs: u32, segment_table: u32, run_table: u32,
    // The host's f64 normals at the corners (0, 0), (1, 0), (0, 1), (1, 1) of the surface's
    // range (grid_common.wgsl's fallback_normal).
    n00_x: f32, n00_y: f32, n00_z: f32,
    n10_x: f32, n10_y: f32, n10_z: f32,
    n01_x: f32, n01_y: f32, n01_z: f32,
    n11_x: f32, n11_y: f32, n11_z: f32,
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
// first column, local parameter step, u fraction (uv) of the first column, u fraction step];
// the general path uses the first two.
const RUN_STRIDE: u32 = 7u;

@group(0) @binding(0) var<uniform> chunk: ChunkParams;
@group(0) @binding(1) var<storage, read> pieces: array<Piece>;
@group(0) @binding(2) var<storage, read> tiles: array<Tile>;
// Control points (P − origin, w).
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

// The homogeneous point of control point `point` relative to `reference`: ((P − R)·w, w).
fn rebased(point: vec4<f32>, reference: vec3<f32>) -> vec4<f32> {
    return vec4<f32>((point.xyz - reference) * point.w, point.w);
}

// vec4 entries of contracted scratch per (run, row) of a general-path piece: the reference,
// then value, ∂v, ∂vv of each of the span's p+1 control columns.
fn contracted_stride(degree_u: u32) -> u32 {
    return 1u + 3u * (degree_u + 1u);
}

// The (run, row) of a path's run-major item: neighbouring invocations (the SIMD lanes of a CPU
// adapter) take the same run of neighbouring rows, so their loops have the same length.
fn run_and_row(piece: Piece, item: u32) -> vec2<u32> {
    return vec2<u32>(item / piece.rows, item % piece.rows);
}

@compute @workgroup_size(64)
fn contract_rows(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
                 @builtin(local_invocation_index) lid: u32) {
    if (wid.x + wid.y * groups.x >= chunk.tile_count) { return; }
    let work = work_item(wid, groups, lid);
    let piece = pieces[work.x];
    if (work.y >= piece.rows * piece.runs) { return; }
    let at = run_and_row(piece, work.y);
    let run = piece.run_table + at.x * RUN_STRIDE - chunk.table_origin;
    let first = bitcast<u32>(tables[run]);
    let count = bitcast<u32>(tables[run + 1u]);
    let p = piece.degree_u;
    let q = piece.degree_v;
    let column = piece.columns + first * entry_stride(p) - chunk.table_origin;
    let span_u = bitcast<u32>(tables[column + 1u]);
    let entry = piece.row_table + at.y * entry_stride(q) - chunk.table_origin;
    let span_v = bitcast<u32>(tables[entry + 1u]);
    let net = piece.points - chunk.point_origin + (span_v - q) * piece.count_u + span_u - p;
    // The reference: for a single vertex (a run where the weights pull hard) its dominant
    // point, the largest basis value × weight there; else the support's first control point.
    var best = -1.0;
    var reference = points[net].xyz;
    for (var b = 0u; b <= select(0u, q, count == 1u); b++) {
        for (var a = 0u; a <= select(0u, p, count == 1u); a++) {
            let point = points[net + b * piece.count_u + a];
            let score = tables[column + 2u + a] * tables[entry + 2u + b] * point.w;
            if (score > best) {
                best = score;
                reference = point.xyz;
            }
        }
    }
    let out = piece.contracted + work.y * contracted_stride(p);
    contracted[out] = vec4<f32>(reference, 0.0);
    for (var a = 0u; a <= p; a++) {
        var value = vec4<f32>(0.0);
        var dv = vec4<f32>(0.0);
        var dvv = vec4<f32>(0.0);
        for (var b = 0u; b <= q; b++) {
            let point = rebased(points[net + b * piece.count_u + a], reference);
            value += tables[entry + 2u + b] * point;
            dv += tables[entry + 3u + q + b] * point;
            dvv += tables[entry + 4u + 2u * q + b] * point;
        }
        contracted[out + 1u + 3u * a] = value;
        contracted[out + 2u + 3u * a] = dv;
        contracted[out + 3u + 3u * a] = dvv;
    }
}

// Writes the vertex whose first vec4 is `out`.
fn store_vertex(out: u32, position: vec3<f32>, normal: vec3<f32>, uv: vec2<f32>) {
    vertices[out] = vec4<f32>(position, normal.x);
    vertices[out + 1u] = vec4<f32>(normal.yz, uv);
}

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

// Whether S_u × S_v is short enough to be checked against its rounding (the first loops'
// cheap test: a vertex that passes it is regular).
fn is_degenerate(piece: Piece, normal: vec3<f32>) -> bool {
    return dot(normal, normal) <= piece.degenerate_sq;
}

// DEGENERATE_EPSILONS (geom::eval) × f32 epsilon: the rounding units of `within_rounding`.
const ROUNDING_FACTOR: f32 = 1.1920929e-5;

// (Σ_b N_b(v)·t_b, Σ_b |N′_b(v)|·t_b) down the control column whose first support point is
// `at`, with the row's basis at table entry `entry`: t = w·(|P| + |R|) bounds the rounding
// the term (P − R)·w carries (the data's and the sums'), zero for a point equal to the
// reference, whose term vanishes exactly.
fn column_rounding(at: u32, count_u: u32, q: u32, entry: u32, reference: vec3<f32>) -> vec2<f32> {
    var sums = vec2<f32>(0.0);
    for (var b = 0u; b <= q; b++) {
        let point = points[at + b * count_u];
        let size = point.w * (length(point.xyz) + length(reference));
        let t = select(size, 0.0, all(point.xyz == reference));
        sums += vec2<f32>(tables[entry + 2u + b], abs(tables[entry + 3u + q + b])) * t;
    }
    return sums;
}

// Whether S_u × S_v of `frame` is within the rounding of its terms, `rounding` = (Σ |∂N/∂u|·t,
// Σ |∂N/∂v|·t) over the support (column_rounding): then it counts as zero and the limit
// normal applies. A vertex the cheap test flags (a size-based threshold) can be regular: a
// heavy weight slows the parametrisation near its point, and S_u × S_v is small there but
// as exact as everywhere.
fn within_rounding(frame: Frame, rounding: vec2<f32>) -> bool {
    let s = length(frame.s);
    let n_u = (rounding.x + abs(frame.au.w) * s) / frame.a.w;
    let n_v = (rounding.y + abs(frame.av.w) * s) / frame.a.w;
    let bound = ROUNDING_FACTOR * (n_u * length(frame.sv) + length(frame.su) * n_v);
    let n = cross(frame.su, frame.sv);
    return dot(n, n) <= bound * bound;
}

// The general path's frame at the grid column whose table entry starts at `column`, from the
// contracted control columns starting at `base`.
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
    if (work.y >= piece.rows * piece.runs) { return; }
    let at = run_and_row(piece, work.y);
    let run = piece.run_table + at.x * RUN_STRIDE - chunk.table_origin;
    let first = bitcast<u32>(tables[run]);
    let last = first + bitcast<u32>(tables[run + 1u]);
    let p = piece.degree_u;
    let stride = entry_stride(p);
    let scratch = piece.contracted + work.y * contracted_stride(p);
    let base = scratch + 1u;
    let origin = vec3<f32>(piece.origin_x, piece.origin_y, piece.origin_z);
    let reference = contracted[scratch].xyz;
    let row_out = piece.first_vertex + at.y * piece.grid_u - chunk.vertex_origin;
    let q = piece.degree_v;
    let entry = piece.row_table + at.y * entry_stride(q) - chunk.table_origin;
    let v_fraction = tables[entry];
    var degenerate = false;
    for (var i = first; i < last; i++) {
        let column = piece.columns + i * stride - chunk.table_origin;
        let frame = general_frame(p, column, base);
        let normal = cross(frame.su, frame.sv);
        degenerate = degenerate | is_degenerate(piece, normal);
        let uv = vec2<f32>(tables[column], v_fraction);
        store_vertex(2u * (row_out + i), origin + (reference + frame.s), normalize(normal), uv);
    }
    // The run's vertices at degenerate points, again, with the limit normal: a second loop
    // rather than a branch in the first, because SIMD-on-CPU adapters (lavapipe) execute a
    // branch that no lane takes but leave a loop once no lane runs it.
    let redo_last = select(first, last, degenerate);
    let span_u = bitcast<u32>(tables[piece.columns + first * stride - chunk.table_origin + 1u]);
    let span_v = bitcast<u32>(tables[entry + 1u]);
    let net = piece.points - chunk.point_origin + (span_v - q) * piece.count_u + span_u - p;
    for (var i = first; i < redo_last; i++) {
        let column = piece.columns + i * stride - chunk.table_origin;
        let frame = general_frame(p, column, base);
        if (is_degenerate(piece, cross(frame.su, frame.sv))) {
            var rounding = vec2<f32>(0.0);
            for (var a = 0u; a <= p; a++) {
                let sums = column_rounding(net + a, piece.count_u, q, entry, reference);
                rounding += vec2<f32>(abs(tables[column + 3u + p + a]) * sums.x, tables[column + 2u + a] * sums.y);
            }
            if (!within_rounding(frame, rounding)) { continue; }
            let uv = vec2<f32>(tables[column], v_fraction);
            let normal = limit_normal(piece, column, base, frame, uv, vec2<u32>(i, piece.first_row + at.y));
            store_vertex(2u * (row_out + i), origin + (reference + frame.s), normalize(normal), uv);
        }
    }
}

// The limit normal where S_u × S_v vanishes (see grid_common.wgsl), from the second
// derivatives of the contracted control columns starting at `base`; `uv` is the grid
// fraction, `at` the vertex's (column, row) in the whole grid.
fn limit_normal(piece: Piece, column: u32, base: u32, frame: Frame, uv: vec2<f32>,
                at: vec2<u32>) -> vec3<f32> {
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
    return limit_normal_from(piece, frame, auu, auv, avv, uv, at);
}

// The limit normal from the homogeneous second derivatives; `uv` is the grid fraction, `at`
// the vertex's (column, row) in the whole grid.
fn limit_normal_from(piece: Piece, frame: Frame, auu: vec4<f32>, auv: vec4<f32>, avv: vec4<f32>,
                     uv: vec2<f32>, at: vec2<u32>) -> vec3<f32> {
    // The first-order term of grid_common.wgsl's first_order_limit_normal, times w, formed
    // from the homogeneous derivatives with the quotient rule's terms along S_u in S_uv and
    // along S_v dropped where they would cross themselves (exactly zero), instead of
    // cancelling in rounding — as geom::eval's first_order_term does in f64.
    let s = frame.s;
    let su = frame.su;
    let sv = frame.sv;
    let n = cross(su, sv);
    let step_u = select(piece.width_u, -piece.width_u, uv.x > 0.5);
    let step_v = select(piece.width_v, -piece.width_v, uv.y > 0.5);
    let along_u = cross(auu.xyz, sv) - 3.0 * frame.au.w * n - auu.w * cross(s, sv)
        + cross(su, auv.xyz) - auv.w * cross(su, s);
    let along_v = cross(auv.xyz, sv) - 3.0 * frame.av.w * n - auv.w * cross(s, sv)
        + cross(su, avv.xyz) - avv.w * cross(su, s);
    let first = step_u * along_u + step_v * along_v;
    let w = frame.a.w;
    if (dot(first, first) <= piece.degenerate_sq * w * w) {
        let corners = array<vec3<f32>, 4>(
            vec3<f32>(piece.n00_x, piece.n00_y, piece.n00_z), vec3<f32>(piece.n10_x, piece.n10_y, piece.n10_z),
            vec3<f32>(piece.n01_x, piece.n01_y, piece.n01_z), vec3<f32>(piece.n11_x, piece.n11_y, piece.n11_z));
        return fallback_normal(corners, at.x, at.y, piece.grid_u, piece.grid_v);
    }
    return first;
}

@compute @workgroup_size(64)
fn evaluate_bezier_runs(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
                        @builtin(local_invocation_index) lid: u32) {
    if (wid.x + wid.y * groups.x >= chunk.tile_count) { return; }
    let work = work_item(wid, groups, lid);
    let piece = pieces[work.x];
    let item = work.y;
    if (item >= piece.rows * piece.runs) { return; }
    let at = run_and_row(piece, item);
    let row = at.y;
    let run = piece.run_table + at.x * RUN_STRIDE - chunk.table_origin;
    let first = bitcast<u32>(tables[run]);
    let count = bitcast<u32>(tables[run + 1u]);
    let segment = piece.segment_table + bitcast<u32>(tables[run + 2u]) * SEGMENT_STRIDE - chunk.table_origin;
    let t0 = tables[run + 3u];
    let dt = tables[run + 4u];
    let u_first = tables[run + 5u];
    let u_step = tables[run + 6u];
    let inv_width = tables[segment + 1u];
    let m0 = matrix_row(segment, 0u);
    let m1 = matrix_row(segment, 1u);
    let m2 = matrix_row(segment, 2u);
    let m3 = matrix_row(segment, 3u);
    // The net contracted along v at this row (value and ∂v; columns: the segment's four
    // control columns, those past the degree repeating the last one, whose matrix entries
    // are zero), relative to the reference: the support's first point, or for a single
    // vertex its dominant point (the B-spline basis there: the Bernstein weights through the
    // segment's matrix).
    let q = piece.degree_v;
    let entry = piece.row_table + row * entry_stride(q) - chunk.table_origin;
    let span = bitcast<u32>(tables[entry + 1u]);
    let net = piece.points - chunk.point_origin + (span - q) * piece.count_u + bitcast<u32>(tables[segment]);
    let last = piece.degree_u;
    var reference = points[net].xyz;
    // A single vertex (a run where the weights pull hard): its dominant point (the loop runs
    // once or not at all: see evaluate_vertices).
    for (var once = 0u; once < select(0u, 1u, count == 1u); once++) {
        let at_t0 = bernstein3(t0);
        let basis_u = at_t0.x * m0 + at_t0.y * m1 + at_t0.z * m2 + at_t0.w * m3;
        var best = -1.0;
        for (var k = 0u; k <= q; k++) {
            for (var c = 0u; c <= last; c++) {
                let point = points[net + k * piece.count_u + c];
                let score = basis_u[c] * tables[entry + 2u + k] * point.w;
                if (score > best) {
                    best = score;
                    reference = point.xyz;
                }
            }
        }
    }
    var value = mat4x4<f32>();
    var value_v = mat4x4<f32>();
    for (var k = 0u; k <= q; k++) {
        let p = support_row(net + k * piece.count_u, last, reference);
        value += tables[entry + 2u + k] * p;
        value_v += tables[entry + 3u + q + k] * p;
    }
    // The span's cubic Bezier form: coefficients of the value, their forward differences,
    // coefficients of ∂v. (What only the limit normals need is formed again in their loop:
    // kept alive through the first loop it would cost the registers that loop runs in.)
    let b = mat4x4<f32>(value * m0, value * m1, value * m2, value * m3);
    let f = mat3x4<f32>(value * matrix_row(segment, 4u), value * matrix_row(segment, 5u),
                        value * matrix_row(segment, 6u));
    let d = mat4x4<f32>(value_v * m0, value_v * m1, value_v * m2, value_v * m3);
    let origin = vec3<f32>(piece.origin_x, piece.origin_y, piece.origin_z);
    let row_out = piece.first_vertex + row * piece.grid_u - chunk.vertex_origin;
    let v_fraction = tables[entry];
    var degenerate = false;
    for (var step = 0u; step < count; step++) {
        let frame = bezier_frame(b, f, d, inv_width, t0 + f32(step) * dt);
        let normal = cross(frame.su, frame.sv);
        degenerate = degenerate | is_degenerate(piece, normal);
        let uv = vec2<f32>(u_first + f32(step) * u_step, v_fraction);
        store_vertex(2u * (row_out + first + step), origin + (reference + frame.s), normalize(normal), uv);
    }
    // The run's vertices at degenerate points, again, with the limit normal (a second loop:
    // see evaluate_vertices).
    // The run's flagged vertices, again (a loop that runs once or not at all, not a branch:
    // see evaluate_vertices): first what the rounding check and the limit normals need —
    // the segment's matrix, the Bezier coefficients of ∂vv, the rounding sums of each
    // control column.
    for (var once = 0u; once < select(0u, 1u, degenerate); once++) {
        var matrix: array<vec4<f32>, 7>;
        var column_sums: array<vec2<f32>, 4>;
        for (var j = 0u; j < 7u; j++) {
            matrix[j] = matrix_row(segment, j);
        }
        var value_vv = mat4x4<f32>();
        for (var k = 0u; k <= q; k++) {
            value_vv += tables[entry + 4u + 2u * q + k] * support_row(net + k * piece.count_u, last, reference);
        }
        let e = mat4x4<f32>(value_vv * matrix[0], value_vv * matrix[1], value_vv * matrix[2], value_vv * matrix[3]);
        for (var c = 0u; c <= last; c++) {
            column_sums[c] = column_rounding(net + c, piece.count_u, q, entry, reference);
        }
        for (var step = 0u; step < count; step++) {
            let t = t0 + f32(step) * dt;
            let frame = bezier_frame(b, f, d, inv_width, t);
            if (is_degenerate(piece, cross(frame.su, frame.sv))) {
                // The B-spline basis of the span's columns at t and its derivative, through the
                // segment's matrix.
                let bt = bernstein3(t);
                let n_u = bt.x * matrix[0] + bt.y * matrix[1] + bt.z * matrix[2] + bt.w * matrix[3];
                let dt3 = bernstein3_derivative(t) * inv_width;
                let dn_u = dt3.x * matrix[4] + dt3.y * matrix[5] + dt3.z * matrix[6];
                var rounding = vec2<f32>(0.0);
                for (var c = 0u; c <= last; c++) {
                    rounding += vec2<f32>(abs(dn_u[c]), abs(n_u[c])) * column_sums[c];
                }
                if (!within_rounding(frame, rounding)) { continue; }
                let s1 = 1.0 - t;
                // ∂uu from the second differences, ∂uv from the differences of ∂v's coefficients.
                let auu = f * vec3<f32>(-s1, s1 - t, t) * (6.0 * inv_width * inv_width);
                let wt = bernstein3_derivative(t);
                let auv = d * vec4<f32>(-wt.x, wt.x - wt.y, wt.y - wt.z, wt.z) * inv_width;
                let avv = e * bt;
                let uv = vec2<f32>(u_first + f32(step) * u_step, v_fraction);
                let normal = limit_normal_from(piece, frame, auu, auv, avv, uv,
                                               vec2<u32>(first + step, piece.first_row + row));
                store_vertex(2u * (row_out + first + step), origin + (reference + frame.s), normalize(normal), uv);
            }
        }
    }
}

// The four support points of a control row starting at `at` (those past the degree `last`
// repeating the last one, whose matrix entries are zero), rebased to `reference`.
fn support_row(at: u32, last: u32, reference: vec3<f32>) -> mat4x4<f32> {
    return mat4x4<f32>(rebased(points[at], reference), rebased(points[at + min(1u, last)], reference),
                       rebased(points[at + min(2u, last)], reference), rebased(points[at + last], reference));
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
