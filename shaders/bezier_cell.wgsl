// Evaluation of a rational Bezier cell at local parameters, shared by the kernels that
// evaluate cells (view.wgsl, points.wgsl; the host prepends this file). The including file
// declares `points` (the cells' nets, vec4<f32>) and `cell_u32(c, word)`, `cell_f32(c, word)`
// over records whose words CELL_DEGENERATE, CELL_DEGREE_U, CELL_DEGREE_V and CELL_NET hold
// |S_u × S_v|² at or below which a point is degenerate, the degrees, and the first point of
// the cell's nets (see src/gpu/view.rs `push_cell_nets`), and whose 12 words from
// CELL_CORNER_NORMALS the host's f64 normals at the cell's corners (0, 0), (1, 0), (0, 1),
// (1, 1) (`corner_normal_words`).

const CELL_DEGENERATE: u32 = 7u;
const CELL_DEGREE_U: u32 = 12u;
const CELL_DEGREE_V: u32 = 13u;
const CELL_NET: u32 = 14u;
const CELL_CORNER_NORMALS: u32 = 24u;

// The Bernstein polynomials of degree n at x (entries 0..=n), by de Casteljau's triangle.
fn bernstein(n: u32, x: f32) -> array<f32, 16> {
    var b: array<f32, 16>;
    b[0] = 1.0;
    for (var d = 1u; d <= n; d++) {
        // Row d from row d − 1 (b[d] is still 0), upward, keeping the old b[i − 1].
        var below = 0.0;
        for (var i = 0u; i <= d; i++) {
            let here = b[i];
            b[i] = (1.0 - x) * here + x * below;
            below = here;
        }
    }
    return b;
}

// A cell's point relative to its centre and its unit normal (S_u × S_v, or its limit where
// that vanishes).
struct CellSample {
    local: vec3<f32>,
    normal: vec3<f32>,
}

// Evaluates cell c at local (s, t) in [0, 1]². The cell's points are its net H and the
// differences of H along u, along v, and the second differences (uu, uv, vv), each formed in
// f64 on the host: derivatives sum differences (the hodographs' nets), so a cell 1e-6 of its
// surface wide keeps its derivatives' digits. Degrees 1..=15.
fn evaluate_cell(c: u32, s: f32, t: f32) -> CellSample {
    let p = cell_u32(c, CELL_DEGREE_U);
    let q = cell_u32(c, CELL_DEGREE_V);
    let net = cell_u32(c, CELL_NET);
    let net_u = net + (p + 1u) * (q + 1u);
    let net_v = net_u + p * (q + 1u);
    let net_uu = net_v + (p + 1u) * q;
    let net_uv = net_uu + (p - 1u) * (q + 1u);
    let net_vv = net_uv + p * q;
    // Degrees p, p − 1 (and p − 2 where degenerate) along u; likewise along v.
    let bu0 = bernstein(p, s);
    let bu1 = bernstein(p - 1u, s);
    let bv0 = bernstein(q, t);
    let bv1 = bernstein(q - 1u, t);
    var h = vec4<f32>(0.0);
    var hu = vec4<f32>(0.0);
    var hv = vec4<f32>(0.0);
    for (var j = 0u; j <= q; j++) {
        for (var i = 0u; i <= p; i++) {
            h += (bu0[i] * bv0[j]) * points[net + j * (p + 1u) + i];
        }
        for (var i = 0u; i < p; i++) {
            hu += (bu1[i] * bv0[j]) * points[net_u + j * p + i];
        }
    }
    for (var j = 0u; j < q; j++) {
        for (var i = 0u; i <= p; i++) {
            hv += (bu0[i] * bv1[j]) * points[net_v + j * (p + 1u) + i];
        }
    }
    let pf = f32(p);
    let qf = f32(q);
    hu *= pf;
    hv *= qf;
    let w = h.w;
    let local = h.xyz / w;
    let su = (hu.xyz - hu.w * local) / w;
    let sv = (hv.xyz - hv.w * local) / w;
    var normal = cross(su, sv);
    let degenerate_sq = cell_f32(c, CELL_DEGENERATE);
    if (dot(normal, normal) <= degenerate_sq) {
        let bu2 = bernstein(max(p, 2u) - 2u, s);
        let bv2 = bernstein(max(q, 2u) - 2u, t);
        var huu = vec4<f32>(0.0);
        var huv = vec4<f32>(0.0);
        var hvv = vec4<f32>(0.0);
        for (var j = 0u; j <= q; j++) {
            for (var i = 0u; i + 1u < p; i++) {
                huu += (bu2[i] * bv0[j]) * points[net_uu + j * (p - 1u) + i];
            }
        }
        for (var j = 0u; j < q; j++) {
            for (var i = 0u; i < p; i++) {
                huv += (bu1[i] * bv1[j]) * points[net_uv + j * p + i];
            }
        }
        for (var j = 0u; j + 1u < q; j++) {
            for (var i = 0u; i <= p; i++) {
                hvv += (bu0[i] * bv2[j]) * points[net_vv + j * (p + 1u) + i];
            }
        }
        huu *= pf * (pf - 1.0);
        huv *= pf * qf;
        hvv *= qf * (qf - 1.0);
        let suu = (huu.xyz - 2.0 * hu.w * su - huu.w * local) / w;
        let suv = (huv.xyz - hu.w * sv - hv.w * su - huv.w * local) / w;
        let svv = (hvv.xyz - 2.0 * hv.w * sv - hvv.w * local) / w;
        // Where the first-order term vanishes too: the host's normal at a corner of the cell
        // (a 2 × 2 grid whose vertices, 0 or 1 each way, are its corners).
        var corners: array<vec3<f32>, 4>;
        for (var k = 0u; k < 4u; k++) {
            let word = CELL_CORNER_NORMALS + 3u * k;
            corners[k] = vec3<f32>(cell_f32(c, word), cell_f32(c, word + 1u), cell_f32(c, word + 2u));
        }
        let i = select(2u, u32(s), s == 0.0 || s == 1.0);
        let j = select(2u, u32(t), t == 0.0 || t == 1.0);
        normal = first_order_limit_normal(su, sv, suu, suv, svv, vec2<f32>(1.0, 1.0),
                                          vec2<f32>(s, t), degenerate_sq,
                                          fallback_normal(corners, i, j, 2u, 2u));
    }
    return CellSample(local, normalize(normal));
}
