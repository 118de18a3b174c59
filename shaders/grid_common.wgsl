// Rules every grid kernel shares (tessellate.wgsl, coons.wgsl): the host prepends this file to
// each of them, so the limit normal and the triangles of a cell are written once.

// Where S_u × S_v vanishes: the first-order term of its expansion along the direction
// (±width_u, ±width_v) pointing to the centre of the range (`uv` is the grid fraction),
//   du (S_u × S_uv + S_uu × S_v) + dv (S_u × S_vv + S_uv × S_v),
// from the Cartesian second derivatives; `fallback` where that vanishes too (see
// fallback_normal). Not normalised. The contract of the f64 reference
// (geom::eval::limit_normal), less its higher orders and nearby points.
fn first_order_limit_normal(su: vec3<f32>, sv: vec3<f32>, suu: vec3<f32>, suv: vec3<f32>,
                            svv: vec3<f32>, width: vec2<f32>, uv: vec2<f32>,
                            degenerate_sq: f32, fallback: vec3<f32>) -> vec3<f32> {
    let step_u = select(width.x, -width.x, uv.x > 0.5);
    let step_v = select(width.y, -width.y, uv.y > 0.5);
    let first = step_u * (cross(su, suv) + cross(suu, sv)) + step_v * (cross(su, svv) + cross(suv, sv));
    if (dot(first, first) <= degenerate_sq) {
        return fallback;
    }
    return first;
}

// What a degenerate vertex (i, j) of an nu × nv grid gets where its first-order limit
// vanishes too: at a corner of the grid the host's f64 limit normal there (`corners` at
// (0, 0), (1, 0), (0, 1), (1, 1) of the range: such a limit takes third derivatives, which
// the kernels do not form, and it is where such points occur — a collapsed edge meeting a
// boundary whose blend or control net leaves the corner with zero slope), elsewhere +Z.
fn fallback_normal(corners: array<vec3<f32>, 4>, i: u32, j: u32, nu: u32, nv: u32) -> vec3<f32> {
    var normals = corners;
    if ((i == 0u || i + 1u == nu) && (j == 0u || j + 1u == nv)) {
        return normals[select(0u, 1u, i > 0u) + select(0u, 2u, j > 0u)];
    }
    return vec3<f32>(0.0, 0.0, 1.0);
}

// The two triangles of the grid cell whose lowest corner is vertex `a` in a grid `grid_u`
// vertices wide: with b = a + 1, c = a + grid_u + 1, d = a + grid_u, the triangles (a, b, c)
// and (a, c, d) — counter-clockwise seen from the S_u × S_v side (as mesh::fill_grid_indices).
fn cell_triangles(a: u32, grid_u: u32) -> array<u32, 6> {
    let c = a + grid_u + 1u;
    return array<u32, 6>(a, a + 1u, c, a, c, a + grid_u);
}
