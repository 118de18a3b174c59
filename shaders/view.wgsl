// View-dependent tessellation, re-planned every frame in one submission: rates → vertex
// counts → their prefix sums (and each cell's first grid row) → triangle counts per grid row
// (which compare vertex indices, so after the vertex layout) → theirs, and the indirect
// draw → vertices → indices. The vertex and row kernels are dispatched indirectly over the
// frame's own vertices and rows, with the workgroup counts the scans write. The host mirror of every rule
// here is src/plan/view.rs (ViewPlan::rates, layout, vertex_samples, triangles); the
// buffer order is the same. grid_common.wgsl is prepended (the limit normal).

struct Frame {
    view_projection: mat4x4<f32>,
    viewport: vec2<f32>,
    tolerance_px: f32,
    margin: f32,
    cells: u32,
    edges: u32,
    corners: u32,
    max_segments: u32,
    // Offsets (in words) of the edge and corner records in `plan`.
    edge_words: u32,
    corner_words: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> frame: Frame;
// Cells (CELL_WORDS each), then edges (EDGE_WORDS), then corners (2): see src/gpu/view.rs.
@group(0) @binding(1) var<storage, read> plan: array<u32>;
// Each cell's homogeneous control points (w·(P − centre), w), u fastest, then their
// differences along u, v, and second differences uu, uv, vv (see write_vertex).
@group(0) @binding(2) var<storage, read> points: array<vec4<f32>>;
// Per frame: rates (2 words per cell), vertex counts (edges, then cells), rows (one word per
// cell), triangle counts (one per grid row of the frame, at most max_segments per cell),
// then the totals (vertices, triangles, rows).
@group(0) @binding(3) var<storage, read_write> work: array<u32>;
// Vertices: position, normal, uv — 8 floats each.
@group(0) @binding(4) var<storage, read_write> vertices: array<f32>;
@group(0) @binding(5) var<storage, read_write> indices: array<u32>;
// DrawIndexedIndirect: index count, instance count, first index, base vertex, first instance.
@group(0) @binding(6) var<storage, read_write> indirect: array<u32>;
// The workgroup counts of the indirect dispatches: over the vertices (0..3), over the rows
// (3..6). Bound (group 1) only while the scans write them.
@group(1) @binding(0) var<storage, read_write> dispatch: array<u32>;

const CELL_WORDS: u32 = 36u;
const EDGE_WORDS: u32 = 5u;
const NO_CELL: u32 = 0xffffffffu;
const BOTTOM: u32 = 0u;
const RIGHT: u32 = 1u;
const TOP: u32 = 2u;
const LEFT: u32 = 3u;
const UNMET: u32 = 0x10000u;
const SCAN_GROUP: u32 = 256u;
// plan::view::PROJECTION_ROUNDING: 8 f32 epsilons.
const PROJECTION_ROUNDING: f32 = 9.5367431640625e-7;

// ---- plan records ----

fn cell_f32(c: u32, word: u32) -> f32 { return bitcast<f32>(plan[c * CELL_WORDS + word]); }
fn cell_u32(c: u32, word: u32) -> u32 { return plan[c * CELL_WORDS + word]; }
fn side_edge(c: u32, side: u32) -> u32 { return cell_u32(c, 16u + side); }
fn side_aligned(c: u32, side: u32) -> bool { return ((cell_u32(c, 15u) >> side) & 1u) == 1u; }
fn cell_corner(c: u32, k: u32) -> u32 { return cell_u32(c, 20u + k); }
fn edge_u32(e: u32, word: u32) -> u32 { return plan[frame.edge_words + e * EDGE_WORDS + word]; }

// ---- work layout ----

fn vertex_counts() -> u32 { return 2u * frame.cells; }
fn row_firsts() -> u32 { return vertex_counts() + frame.edges + frame.cells; }
fn triangle_counts() -> u32 { return row_firsts() + frame.cells; }
fn totals() -> u32 { return triangle_counts() + frame.cells * frame.max_segments; }
fn rate(c: u32) -> vec2<u32> { return vec2<u32>(work[2u * c], work[2u * c + 1u] & 0xffffu); }
fn side_rate(c: u32, side: u32) -> u32 {
    let r = rate(c);
    return select(r.y, r.x, side == BOTTOM || side == TOP);
}
fn edge_first(e: u32) -> u32 { return work[vertex_counts() + e]; }
fn cell_first(c: u32) -> u32 { return work[vertex_counts() + frame.edges + c]; }

fn flat_index(gid: vec3<u32>, groups: vec3<u32>) -> u32 {
    return gid.x + gid.y * groups.x * 64u;
}

fn gcd(a0: u32, b0: u32) -> u32 {
    var a = a0;
    var b = b0;
    while (b != 0u) {
        let r = a % b;
        a = b;
        b = r;
    }
    return a;
}

// ---- rates ----

fn deviation(abc: vec3<f32>, nu: f32, nv: f32) -> f32 {
    return abc.x / (nu * nu) + abc.y / (nu * nv) + abc.z / (nv * nv);
}

// The cell's segments (and UNMET in y where the tolerance is not met): see
// plan::view::rate_for and fewest_segments.
fn cell_rate(c: u32) -> vec2<u32> {
    let m = transpose(frame.view_projection);
    let rx = m[0];
    let ry = m[1];
    let rz = m[2];
    let rw = m[3];
    let centre = vec4<f32>(cell_f32(c, 0u), cell_f32(c, 1u), cell_f32(c, 2u), 1.0);
    let r = cell_f32(c, 3u);
    var planes = array<vec4<f32>, 6>(rw + rx, rw - rx, rw + ry, rw - ry, rz, rw - rz);
    // Each dot product widened by its rounding (plan::view::PROJECTION_ROUNDING).
    let a = abs(centre);
    for (var k = 0u; k < 6u; k++) {
        let p = planes[k];
        if (dot(p, centre) < -r * length(p.xyz) - PROJECTION_ROUNDING * dot(abs(p), a)) {
            return vec2<u32>(1u, 1u);
        }
    }
    let most = vec2<u32>(frame.max_segments, frame.max_segments | UNMET);
    let w_norm = length(rw.xyz);
    let w_min = dot(rw, centre) - r * w_norm - PROJECTION_ROUNDING * dot(abs(rw), a);
    if (w_min <= 0.0) {
        return most;
    }
    let nx = length(rx.xyz);
    let ny = length(ry.xyz);
    let ndc_x = (abs(dot(rx, centre)) + r * nx + PROJECTION_ROUNDING * dot(abs(rx), a)) / w_min;
    let ndc_y = (abs(dot(ry, centre)) + r * ny + PROJECTION_ROUNDING * dot(abs(ry), a)) / w_min;
    let gx = 0.5 * frame.viewport.x * (nx + ndc_x * w_norm) / w_min;
    let gy = 0.5 * frame.viewport.y * (ny + ndc_y * w_norm) / w_min;
    let tolerance = frame.margin * frame.tolerance_px / sqrt(gx * gx + gy * gy);
    let abc = vec3<f32>(cell_f32(c, 4u), cell_f32(c, 5u), cell_f32(c, 6u));
    let cap = f32(frame.max_segments);
    var best = most;
    var best_cells = 0xffffffffu;
    for (var n_u = 1u; n_u <= frame.max_segments; n_u++) {
        let nu = f32(n_u);
        let rest = tolerance - abc.x / (nu * nu);
        if (rest <= 0.0) {
            continue;
        }
        let beta = abc.y / nu;
        let least = (beta + sqrt(beta * beta + 4.0 * abc.z * rest)) / (2.0 * rest);
        var nv = max(ceil(least), 1.0);
        if (nv > cap) {
            continue;
        }
        while (nv < cap && deviation(abc, nu, nv) > tolerance) {
            nv += 1.0;
        }
        if (deviation(abc, nu, nv) > tolerance) {
            continue;
        }
        let n_v = u32(nv);
        if (n_u * n_v < best_cells) {
            best = vec2<u32>(n_u, n_v);
            best_cells = n_u * n_v;
        }
    }
    return best;
}

@compute @workgroup_size(64)
fn cell_rates(@builtin(global_invocation_id) gid: vec3<u32>,
              @builtin(num_workgroups) groups: vec3<u32>) {
    let c = flat_index(gid, groups);
    if (c >= frame.cells) {
        return;
    }
    let r = cell_rate(c);
    work[2u * c] = r.x;
    work[2u * c + 1u] = r.y;
    let n = r.y & 0xffffu;
    work[vertex_counts() + frame.edges + c] = (r.x - 1u) * (n - 1u);
    work[row_firsts() + c] = n;
}

// The last x in [0, n) with work[start + x] ≤ value, for ascending entries with
// work[start] ≤ value: the entry whose range holds `value` (empty ranges are skipped, their
// successor starting where they do).
fn last_at_most(start: u32, n: u32, value: u32) -> u32 {
    var low = 0u;
    var high = n;
    while (high - low > 1u) {
        let middle = (low + high) / 2u;
        if (work[start + middle] <= value) {
            low = middle;
        } else {
            high = middle;
        }
    }
    return low;
}

// ---- edges ----

fn edge_samples(e: u32) -> u32 {
    if (edge_u32(e, 4u) != 0u) {
        return 0u;
    }
    let n_a = side_rate(edge_u32(e, 0u), edge_u32(e, 1u));
    let other = edge_u32(e, 2u);
    if (other == NO_CELL) {
        return n_a - 1u;
    }
    let n_b = side_rate(other, edge_u32(e, 3u));
    return n_a + n_b - gcd(n_a, n_b) - 1u;
}

@compute @workgroup_size(64)
fn edge_counts(@builtin(global_invocation_id) gid: vec3<u32>,
               @builtin(num_workgroups) groups: vec3<u32>) {
    let e = flat_index(gid, groups);
    if (e >= frame.edges) {
        return;
    }
    work[vertex_counts() + e] = edge_samples(e);
}

fn other_rank(t: u32, n_a: u32, n_b: u32) -> u32 {
    let step = n_b / gcd(n_a, n_b);
    return (t - 1u) - (t - 1u) / step;
}

fn other_sample(k: u32, n_a: u32, n_b: u32) -> u32 {
    let step = n_b / gcd(n_a, n_b);
    return 1u + k + k / max(step - 1u, 1u);
}

// ---- vertex indices (plan::view::Frame) ----

// The corners (as the cell's corner words) where a side starts and ends in the cell's own
// direction: bottom c00 → c10, right c10 → c11, top c01 → c11, left c00 → c01.
fn side_start(side: u32) -> u32 {
    return select(select(0u, 3u, side == TOP), 1u, side == RIGHT);
}
fn side_end(side: u32) -> u32 {
    return select(select(2u, 3u, side == LEFT), 1u, side == BOTTOM);
}

fn side_vertex(c: u32, side: u32, s: u32) -> u32 {
    let n = side_rate(c, side);
    let e = side_edge(c, side);
    if (s == 0u || edge_u32(e, 4u) != 0u) {
        return cell_corner(c, side_start(side));
    }
    if (s == n) {
        return cell_corner(c, side_end(side));
    }
    let first = edge_first(e);
    let t = select(n - s, s, side_aligned(c, side));
    if (edge_u32(e, 0u) == c && edge_u32(e, 1u) == side) {
        return first + t - 1u;
    }
    let n_a = side_rate(edge_u32(e, 0u), edge_u32(e, 1u));
    if ((t * n_a) % n == 0u) {
        return first + t * n_a / n - 1u;
    }
    return first + (n_a - 1u) + other_rank(t, n_a, n);
}

fn grid_vertex(c: u32, i: u32, j: u32) -> u32 {
    let r = rate(c);
    if (j == 0u) {
        return side_vertex(c, BOTTOM, i);
    }
    if (j == r.y) {
        return side_vertex(c, TOP, i);
    }
    if (i == 0u) {
        return side_vertex(c, LEFT, j);
    }
    if (i == r.x) {
        return side_vertex(c, RIGHT, j);
    }
    return cell_first(c) + (j - 1u) * (r.x - 1u) + (i - 1u);
}

// The other cell's samples strictly inside segment k of `side` of cell c: r from `first`,
// `count` of them (r in the cell's own direction at the other cell's rate).
struct Extras {
    first: u32,
    count: u32,
}

fn extras(c: u32, side: u32, k: u32, on: bool) -> Extras {
    if (!on) {
        return Extras(0u, 0u);
    }
    let e = side_edge(c, side);
    if (edge_u32(e, 4u) != 0u || edge_u32(e, 2u) == NO_CELL) {
        return Extras(0u, 0u);
    }
    let n = side_rate(c, side);
    let owner_here = edge_u32(e, 0u) == c && edge_u32(e, 1u) == side;
    let y = select(edge_u32(e, 0u), edge_u32(e, 2u), owner_here);
    let y_side = select(edge_u32(e, 1u), edge_u32(e, 3u), owner_here);
    let m = side_rate(y, y_side);
    let low = k * m / n + 1u;
    // r·n < (k + 1)·m for r = low .. low + count − 1.
    let high = ((k + 1u) * m - 1u) / n;
    return Extras(low, select(0u, high + 1u - low, high >= low));
}

fn extra_vertex(c: u32, side: u32, r: u32) -> u32 {
    let e = side_edge(c, side);
    let owner_here = edge_u32(e, 0u) == c && edge_u32(e, 1u) == side;
    let y = select(edge_u32(e, 0u), edge_u32(e, 2u), owner_here);
    let y_side = select(edge_u32(e, 1u), edge_u32(e, 3u), owner_here);
    let m = side_rate(y, y_side);
    let t = select(m - r, r, side_aligned(c, side));
    let first = edge_first(e);
    if (owner_here) {
        let n_a = side_rate(c, side);
        return first + (n_a - 1u) + other_rank(t, n_a, m);
    }
    return first + t - 1u;
}

// Chain a: c00, bottom extras, c10, right extras, c11. Chain b: c00, left extras, c01, top
// extras, c11 (plan::adaptive::zip_chains).
fn chain(c: u32, q0: u32, q1: u32, q2: u32, side1: u32, x1: Extras, side2: u32, x2: Extras,
         k: u32) -> u32 {
    if (k == 0u) {
        return q0;
    }
    if (k <= x1.count) {
        return extra_vertex(c, side1, x1.first + k - 1u);
    }
    if (k == x1.count + 1u) {
        return q1;
    }
    let m = k - x1.count - 2u;
    if (m < x2.count) {
        return extra_vertex(c, side2, x2.first + m);
    }
    return q2;
}

fn emit(write: bool, base: u32, count: ptr<function, u32>, a: u32, b: u32, d: u32) {
    if (a == b || b == d || d == a) {
        return;
    }
    if (write) {
        let o = 3u * (base + *count);
        indices[o] = a;
        indices[o + 1u] = b;
        indices[o + 2u] = d;
    }
    *count += 1u;
}

// The triangles of grid row j of cell c, written from triangle `base` when `write`; returns
// how many (plan::view::Frame::row_triangles).
fn row_triangles(c: u32, j: u32, write: bool, base: u32) -> u32 {
    let r = rate(c);
    var count = 0u;
    // Rows whose grid cells' corners are all inside the cell, but at the ends: the grid rule
    // on interior vertices, numbered row by row from the cell's first.
    let inner_row = j >= 1u && j + 2u <= r.y;
    let first = cell_first(c);
    let stride = r.x - 1u;
    for (var i = 0u; i < r.x; i++) {
        if (inner_row && i >= 1u && i + 2u <= r.x) {
            let a = first + (j - 1u) * stride + (i - 1u);
            emit(write, base, &count, a, a + 1u, a + stride + 1u);
            emit(write, base, &count, a, a + stride + 1u, a + stride);
            continue;
        }
        let q00 = grid_vertex(c, i, j);
        let q10 = grid_vertex(c, i + 1u, j);
        let q11 = grid_vertex(c, i + 1u, j + 1u);
        let q01 = grid_vertex(c, i, j + 1u);
        let bottom = extras(c, BOTTOM, i, j == 0u);
        let right = extras(c, RIGHT, j, i + 1u == r.x);
        let top = extras(c, TOP, i, j + 1u == r.y);
        let left = extras(c, LEFT, j, i == 0u);
        if (bottom.count + right.count + top.count + left.count == 0u) {
            // cell_triangles of the corners: (c00, c10, c11), (c00, c11, c01).
            emit(write, base, &count, q00, q10, q11);
            emit(write, base, &count, q00, q11, q01);
            continue;
        }
        let last_a = 2u + bottom.count + right.count;
        let last_b = 2u + left.count + top.count;
        emit(write, base, &count, q00,
             chain(c, q00, q10, q11, BOTTOM, bottom, RIGHT, right, 1u),
             chain(c, q00, q01, q11, LEFT, left, TOP, top, 1u));
        var a = 1u;
        var b = 1u;
        while (a + 1u < last_a || b + 1u < last_b) {
            let advance_a = b + 1u == last_b || (a + 1u < last_a && (a + 1u) * last_b <= (b + 1u) * last_a);
            if (advance_a) {
                emit(write, base, &count,
                     chain(c, q00, q10, q11, BOTTOM, bottom, RIGHT, right, a),
                     chain(c, q00, q10, q11, BOTTOM, bottom, RIGHT, right, a + 1u),
                     chain(c, q00, q01, q11, LEFT, left, TOP, top, b));
                a += 1u;
            } else {
                emit(write, base, &count,
                     chain(c, q00, q01, q11, LEFT, left, TOP, top, b + 1u),
                     chain(c, q00, q01, q11, LEFT, left, TOP, top, b),
                     chain(c, q00, q10, q11, BOTTOM, bottom, RIGHT, right, a));
                b += 1u;
            }
        }
        emit(write, base, &count,
             chain(c, q00, q10, q11, BOTTOM, bottom, RIGHT, right, last_a - 1u),
             q11,
             chain(c, q00, q01, q11, LEFT, left, TOP, top, last_b - 1u));
    }
    return count;
}

// The cell and grid row of frame row r.
fn row_of(r: u32) -> vec2<u32> {
    let c = last_at_most(row_firsts(), frame.cells, r);
    return vec2<u32>(c, r - work[row_firsts() + c]);
}

@compute @workgroup_size(64)
fn row_counts(@builtin(global_invocation_id) gid: vec3<u32>,
              @builtin(num_workgroups) groups: vec3<u32>) {
    let r = flat_index(gid, groups);
    if (r >= work[totals() + 2u]) {
        return;
    }
    let row = row_of(r);
    work[triangle_counts() + r] = row_triangles(row.x, row.y, false, 0u);
}

// ---- prefix sums (one workgroup) ----

var<workgroup> partial: array<u32, SCAN_GROUP>;
var<workgroup> scan_count: u32;

// Exclusive prefix sums of work[start .. start + count] in place, from `offset`; returns the
// total (offset included) in every invocation. Called in uniform control flow; `count` is
// made uniform through workgroup memory, so every loop around a barrier has uniform bounds
// (WebGPU's uniformity rules).
fn scan(start: u32, count_in: u32, offset: u32, lid: u32) -> u32 {
    // `partial` and `scan_count` may still be read by a previous scan.
    workgroupBarrier();
    if (lid == 0u) {
        scan_count = count_in;
    }
    let count = workgroupUniformLoad(&scan_count);
    let chunk = (count + SCAN_GROUP - 1u) / SCAN_GROUP;
    var sum = 0u;
    for (var k = 0u; k < chunk; k++) {
        let x = lid * chunk + k;
        if (x < count) {
            sum += work[start + x];
        }
    }
    partial[lid] = sum;
    workgroupBarrier();
    for (var d = 1u; d < SCAN_GROUP; d *= 2u) {
        var below = 0u;
        if (lid >= d) {
            below = partial[lid - d];
        }
        workgroupBarrier();
        partial[lid] += below;
        workgroupBarrier();
    }
    var run = offset + partial[lid] - sum;
    for (var k = 0u; k < chunk; k++) {
        let x = lid * chunk + k;
        if (x < count) {
            let value = work[start + x];
            work[start + x] = run;
            run += value;
        }
    }
    return offset + partial[SCAN_GROUP - 1u];
}

// Workgroups of 64 covering `items` invocations, folded into two dimensions past 65535
// (as flat_index unfolds them), at dispatch[at..at + 3].
fn write_dispatch(at: u32, items: u32) {
    let groups = (items + 63u) / 64u;
    let x = min(groups, 65535u);
    dispatch[at] = x;
    dispatch[at + 1u] = select(0u, (groups + x - 1u) / max(x, 1u), groups > 0u);
    dispatch[at + 2u] = 1u;
}

@compute @workgroup_size(256)
fn scan_vertices(@builtin(local_invocation_index) lid: u32) {
    let vertices = scan(vertex_counts(), frame.edges + frame.cells, frame.corners, lid);
    let rows = scan(row_firsts(), frame.cells, 0u, lid);
    if (lid == 0u) {
        work[totals()] = vertices;
        work[totals() + 2u] = rows;
        write_dispatch(0u, vertices);
        write_dispatch(3u, rows);
    }
}

@compute @workgroup_size(256)
fn scan_triangles(@builtin(local_invocation_index) lid: u32) {
    let total = scan(triangle_counts(), work[totals() + 2u], 0u, lid);
    if (lid == 0u) {
        work[totals() + 1u] = total;
        indirect[0] = 3u * total;
        indirect[1] = 1u;
        indirect[2] = 0u;
        indirect[3] = 0u;
        indirect[4] = 0u;
    }
}

// ---- vertices ----

// Evaluates cell c at local (s, t) into vertex `index` (evaluate_cell, bezier_cell.wgsl).
fn write_vertex(index: u32, c: u32, s: f32, t: f32) {
    let sample = evaluate_cell(c, s, t);
    let local = sample.local;
    let normal = sample.normal;
    let centre = vec3<f32>(cell_f32(c, 0u), cell_f32(c, 1u), cell_f32(c, 2u));
    let position = centre + local;
    let uv = vec2<f32>(cell_f32(c, 8u), cell_f32(c, 9u))
        + vec2<f32>(s, t) * vec2<f32>(cell_f32(c, 10u), cell_f32(c, 11u));
    let o = 8u * index;
    vertices[o] = position.x;
    vertices[o + 1u] = position.y;
    vertices[o + 2u] = position.z;
    vertices[o + 3u] = normal.x;
    vertices[o + 4u] = normal.y;
    vertices[o + 5u] = normal.z;
    vertices[o + 6u] = uv.x;
    vertices[o + 7u] = uv.y;
}

fn on_side(side: u32, f: f32) -> vec2<f32> {
    switch (side) {
        case 0u: { return vec2<f32>(f, 0.0); }
        case 1u: { return vec2<f32>(1.0, f); }
        case 2u: { return vec2<f32>(f, 1.0); }
        default: { return vec2<f32>(0.0, f); }
    }
}

// Vertex v of the frame: a corner, an edge's sample, or a cell's interior vertex.
@compute @workgroup_size(64)
fn evaluate_vertices(@builtin(global_invocation_id) gid: vec3<u32>,
                     @builtin(num_workgroups) groups: vec3<u32>) {
    let v = flat_index(gid, groups);
    if (v >= work[totals()]) {
        return;
    }
    if (v < frame.corners) {
        let c = plan[frame.corner_words + 2u * v];
        let corner = plan[frame.corner_words + 2u * v + 1u];
        write_vertex(v, c, select(0.0, 1.0, corner == 1u || corner == 2u),
                     select(0.0, 1.0, corner >= 2u));
        return;
    }
    let x = last_at_most(vertex_counts(), frame.edges + frame.cells, v);
    let k = v - work[vertex_counts() + x];
    if (x < frame.edges) {
        let e = x;
        let owner = edge_u32(e, 0u);
        let side = edge_u32(e, 1u);
        let n_a = side_rate(owner, side);
        var f: f32;
        if (k < n_a - 1u) {
            f = f32(k + 1u) / f32(n_a);
        } else {
            let n_b = side_rate(edge_u32(e, 2u), edge_u32(e, 3u));
            f = f32(other_sample(k - (n_a - 1u), n_a, n_b)) / f32(n_b);
        }
        let st = on_side(side, f);
        write_vertex(v, owner, st.x, st.y);
        return;
    }
    let c = x - frame.edges;
    let r = rate(c);
    let i = k % (r.x - 1u) + 1u;
    let j = k / (r.x - 1u) + 1u;
    write_vertex(v, c, f32(i) / f32(r.x), f32(j) / f32(r.y));
}

// ---- indices ----

@compute @workgroup_size(64)
fn row_indices(@builtin(global_invocation_id) gid: vec3<u32>,
               @builtin(num_workgroups) groups: vec3<u32>) {
    let r = flat_index(gid, groups);
    if (r >= work[totals() + 2u]) {
        return;
    }
    let row = row_of(r);
    row_triangles(row.x, row.y, true, work[triangle_counts() + r]);
}
