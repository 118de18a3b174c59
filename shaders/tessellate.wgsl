// Grid tessellation of rational tensor-product B-spline surfaces, in f32.
//
// The host (src/gpu/pack.rs) splits every surface into pieces (bands of grid rows), computes
// basis values in f64 and uploads them with the control points, which are stored relative to
// the surface's own origin. One workgroup per tile of 64 work items; five passes, of which a
// piece takes three. Pieces of degree ≤ 3 along u (the Bezier-run path):
//   bezier_rows          — per grid row and knot span along u touched by the grid: the net
//                          contracted along v, then turned into the span's cubic Bezier form
//                          (value, ∂v, ∂vv) by a host-computed matrix; the value's forward
//                          differences too, which keep ∂u exact in f32 over tiny spans;
//   evaluate_bezier_runs — per run of vertices along a row inside one span: the coefficients
//                          loaded once into registers, each vertex a cubic in the span-local
//                          parameter (no per-vertex loads: what decides speed on SIMD-on-CPU
//                          implementations such as lavapipe, where every storage access is a
//                          loop over the lanes).
// Pieces of higher degree along u (the general path), from basis tables of every grid column:
//   contract_rows        — per grid row and control column: the control net contracted along
//                          v (value, ∂v, ∂vv; homogeneous);
//   evaluate_vertices    — per run of vertices along a row: contraction along u of p+1 of
//                          those.
// Both evaluations apply the quotient rule and compute the unit normal (the limit from second
// derivatives where S_u × S_v vanishes); position = origin + local point, added last. Then
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
// vec4 entries per (row, segment) of the scratch: b0..b3, f1..f3, d0..d3, e0..e3.
const BEZIER_ENTRIES: u32 = 15u;

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

// Vertices one invocation evaluates: a run along u of one grid row, sharing the row's data
// (fewer loads per vertex: what decides speed on SIMD-on-CPU implementations such as
// lavapipe, where every per-invocation load is a gather).
const RUN: u32 = 8u;

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
    let v_fraction = tables[piece.row_table + row * entry_stride(piece.degree_v) - chunk.table_origin];
    let origin = vec3<f32>(piece.origin_x, piece.origin_y, piece.origin_z);
    var out = 2u * (piece.first_vertex + row * piece.grid_u + first - chunk.vertex_origin);
    for (var i = first; i < last; i++) {
        let column = piece.columns + i * stride - chunk.table_origin;
        let span = bitcast<u32>(tables[column + 1u]);
        let base = row_base + 3u * (span - p);
        // Homogeneous A, A_u, A_v.
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
        let s = a.xyz / a.w;
        let su = (au.xyz - au.w * s) / a.w;
        let sv = (av.xyz - av.w * s) / a.w;
        var normal = cross(su, sv);
        if (dot(normal, normal) <= piece.degenerate_sq) {
            normal = limit_normal(piece, column, base, a, au, av, s, su, sv, v_fraction);
        }
        normal = normalize(normal);
        vertices[out] = vec4<f32>(s + origin, normal.x);
        vertices[out + 1u] = vec4<f32>(normal.yz, tables[column], v_fraction);
        out += 2u;
    }
}

// Where S_u × S_v vanishes: the first-order term of its expansion along the direction
// (±width_u, ±width_v) pointing to the centre of the range,
//   du (S_u × S_uv + S_uu × S_v) + dv (S_u × S_vv + S_uv × S_v),
// from the second derivatives; +Z where that vanishes too (no tangent plane nearby).
fn limit_normal(piece: Piece, column: u32, base: u32, a: vec4<f32>, au: vec4<f32>, av: vec4<f32>,
                s: vec3<f32>, su: vec3<f32>, sv: vec3<f32>, v_fraction: f32) -> vec3<f32> {
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
    return limit_normal_from(piece, a, au, av, auu, auv, avv, s, su, sv,
                             vec2<f32>(tables[column], v_fraction));
}

// The limit normal from the homogeneous second derivatives; `uv` is the grid fraction.
fn limit_normal_from(piece: Piece, a: vec4<f32>, au: vec4<f32>, av: vec4<f32>, auu: vec4<f32>,
                     auv: vec4<f32>, avv: vec4<f32>, s: vec3<f32>, su: vec3<f32>, sv: vec3<f32>,
                     uv: vec2<f32>) -> vec3<f32> {
    let w = a.w;
    let suu = (auu.xyz - 2.0 * au.w * su - auu.w * s) / w;
    let suv = (auv.xyz - au.w * sv - av.w * su - auv.w * s) / w;
    let svv = (avv.xyz - 2.0 * av.w * sv - avv.w * s) / w;
    let step_u = select(piece.width_u, -piece.width_u, uv.x > 0.5);
    let step_v = select(piece.width_v, -piece.width_v, uv.y > 0.5);
    let first = step_u * (cross(su, suv) + cross(suu, sv)) + step_v * (cross(su, svv) + cross(suv, sv));
    if (dot(first, first) <= piece.degenerate_sq) {
        return vec3<f32>(0.0, 0.0, 1.0);
    }
    return first;
}

@compute @workgroup_size(64)
fn bezier_rows(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
               @builtin(local_invocation_index) lid: u32) {
    if (wid.x + wid.y * groups.x >= chunk.tile_count) { return; }
    let work = work_item(wid, groups, lid);
    let piece = pieces[work.x];
    let item = work.y;
    if (item >= piece.rows * piece.segments) { return; }
    let row = item / piece.segments;
    let segment = piece.segment_table + (item % piece.segments) * SEGMENT_STRIDE - chunk.table_origin;
    let first_column = bitcast<u32>(tables[segment]);
    let q = piece.degree_v;
    let entry = piece.row_table + row * entry_stride(q) - chunk.table_origin;
    let span = bitcast<u32>(tables[entry + 1u]);
    let net = piece.points - chunk.point_origin + (span - q) * piece.count_u + first_column;
    // The net contracted along v (value, ∂v, ∂vv) at the segment's control columns, four
    // (columns past the degree repeat the last one; their matrix entries are zero).
    let last = piece.degree_u;
    var value0 = vec4<f32>(0.0); var value1 = vec4<f32>(0.0); var value2 = vec4<f32>(0.0); var value3 = vec4<f32>(0.0);
    var dv0 = vec4<f32>(0.0); var dv1 = vec4<f32>(0.0); var dv2 = vec4<f32>(0.0); var dv3 = vec4<f32>(0.0);
    var dvv0 = vec4<f32>(0.0); var dvv1 = vec4<f32>(0.0); var dvv2 = vec4<f32>(0.0); var dvv3 = vec4<f32>(0.0);
    for (var k = 0u; k <= q; k++) {
        let n = vec3<f32>(tables[entry + 2u + k], tables[entry + 3u + q + k], tables[entry + 4u + 2u * q + k]);
        let first = net + k * piece.count_u;
        let p0 = points[first];
        let p1 = points[first + min(1u, last)];
        let p2 = points[first + min(2u, last)];
        let p3 = points[first + last];
        value0 += n.x * p0; value1 += n.x * p1; value2 += n.x * p2; value3 += n.x * p3;
        dv0 += n.y * p0; dv1 += n.y * p1; dv2 += n.y * p2; dv3 += n.y * p3;
        dvv0 += n.z * p0; dvv1 += n.z * p1; dvv2 += n.z * p2; dvv3 += n.z * p3;
    }
    // Scratch: Bezier coefficients of the value (4), their forward differences (3), the
    // coefficients of ∂v (4) and ∂vv (4).
    let out = piece.contracted + BEZIER_ENTRIES * item;
    for (var j = 0u; j < 7u; j++) {
        let m = segment + 2u + 4u * j;
        let row = vec4<f32>(tables[m], tables[m + 1u], tables[m + 2u], tables[m + 3u]);
        contracted[out + j] = row.x * value0 + row.y * value1 + row.z * value2 + row.w * value3;
        if (j < 4u) {
            contracted[out + 7u + j] = row.x * dv0 + row.y * dv1 + row.z * dv2 + row.w * dv3;
            contracted[out + 11u + j] = row.x * dvv0 + row.y * dvv1 + row.z * dvv2 + row.w * dvv3;
        }
    }
}

@compute @workgroup_size(64)
fn evaluate_bezier_runs(@builtin(workgroup_id) wid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
                        @builtin(local_invocation_index) lid: u32) {
    if (wid.x + wid.y * groups.x >= chunk.tile_count) { return; }
    let work = work_item(wid, groups, lid);
    let piece = pieces[work.x];
    let item = work.y;
    if (item >= piece.rows * piece.runs) { return; }
    let row = item / piece.runs;
    let run = piece.run_table + (item % piece.runs) * RUN_STRIDE - chunk.table_origin;
    let first = bitcast<u32>(tables[run]);
    let count = bitcast<u32>(tables[run + 1u]);
    let segment = bitcast<u32>(tables[run + 2u]);
    let t0 = tables[run + 3u];
    let dt = tables[run + 4u];
    let inv_width = tables[piece.segment_table + segment * SEGMENT_STRIDE + 1u - chunk.table_origin];
    let coefficients = piece.contracted + BEZIER_ENTRIES * (row * piece.segments + segment);
    let b0 = contracted[coefficients];
    let b1 = contracted[coefficients + 1u];
    let b2 = contracted[coefficients + 2u];
    let b3 = contracted[coefficients + 3u];
    let f1 = contracted[coefficients + 4u];
    let f2 = contracted[coefficients + 5u];
    let f3 = contracted[coefficients + 6u];
    let d0 = contracted[coefficients + 7u];
    let d1 = contracted[coefficients + 8u];
    let d2 = contracted[coefficients + 9u];
    let d3 = contracted[coefficients + 10u];
    // ∂vv only feeds the limit normal, but loads inside that rare branch would cost every
    // vertex on SIMD-on-CPU adapters (lavapipe masks a branch rather than skipping it).
    let e0 = contracted[coefficients + 11u];
    let e1 = contracted[coefficients + 12u];
    let e2 = contracted[coefficients + 13u];
    let e3 = contracted[coefficients + 14u];
    let v_fraction = tables[piece.row_table + row * entry_stride(piece.degree_v) - chunk.table_origin];
    let origin = vec3<f32>(piece.origin_x, piece.origin_y, piece.origin_z);
    let row_out = piece.first_vertex + row * piece.grid_u - chunk.vertex_origin;
    let u_scale = 1.0 / f32(piece.grid_u - 1u);
    for (var step = 0u; step < count; step++) {
        let i = first + step;
        let t = t0 + f32(step) * dt;
        let s1 = 1.0 - t;
        // Cubic Bernstein weights, and the weights of the differences in the t-derivative.
        let w = vec4<f32>(s1 * s1 * s1, 3.0 * t * s1 * s1, 3.0 * t * t * s1, t * t * t);
        let wt = vec3<f32>(3.0 * s1 * s1, 6.0 * t * s1, 3.0 * t * t);
        // Homogeneous A, A_u, A_v.
        let a = w.x * b0 + w.y * b1 + w.z * b2 + w.w * b3;
        let au = (wt.x * f1 + wt.y * f2 + wt.z * f3) * inv_width;
        let av = w.x * d0 + w.y * d1 + w.z * d2 + w.w * d3;
        let s = a.xyz / a.w;
        let su = (au.xyz - au.w * s) / a.w;
        let sv = (av.xyz - av.w * s) / a.w;
        let uv = vec2<f32>(f32(i) * u_scale, v_fraction);
        var normal = cross(su, sv);
        if (dot(normal, normal) <= piece.degenerate_sq) {
            let auu = 6.0 * (s1 * (f2 - f1) + t * (f3 - f2)) * (inv_width * inv_width);
            let auv = (wt.x * (d1 - d0) + wt.y * (d2 - d1) + wt.z * (d3 - d2)) * inv_width;
            let avv = w.x * e0 + w.y * e1 + w.z * e2 + w.w * e3;
            normal = limit_normal_from(piece, a, au, av, auu, auv, avv, s, su, sv, uv);
        }
        normal = normalize(normal);
        let out = 2u * (row_out + i);
        vertices[out] = vec4<f32>(s + origin, normal.x);
        vertices[out + 1u] = vec4<f32>(normal.yz, uv);
    }
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
    let a = piece.first_vertex + row * piece.grid_u + i;
    let b = a + 1u;
    let c = a + piece.grid_u + 1u;
    let d = a + piece.grid_u;
    let out = piece.first_index + 6u * item - chunk.index_origin;
    indices[out] = a;
    indices[out + 1u] = b;
    indices[out + 2u] = c;
    indices[out + 3u] = a;
    indices[out + 4u] = c;
    indices[out + 5u] = d;
}
