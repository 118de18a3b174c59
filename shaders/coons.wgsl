// Coons patches evaluated directly, in f32: for blends with no exact B-spline form.
//
// curves.wgsl first samples every patch's four boundary curves (position, C′, C″ relative to
// the patch origin) at the grid's columns and rows; the host (src/gpu/coons.rs) tabulates
// the blend α, 1 − α (without cancellation), α′, α″ there in f64. One invocation per vertex combines them by the Coons
// formula
//   S = α(v)S(u,0) + (1−α(v))S(u,1) + α(u)S(0,v) + (1−α(u))S(1,v) − corner terms,
// differentiated factor by factor, takes unit(S_u × S_v) (its first-order limit where that
// vanishes: grid_common.wgsl), adds the origin last, and writes the two triangles of the
// cell it starts.
// Only core WGSL and f32.

// Mirrors src/gpu/coons.rs `CoonsJob`: all scalars, 144 bytes.
struct CoonsJob {
    origin_x: f32, origin_y: f32, origin_z: f32,
    // |S_u × S_v|² at or below this (model units², unit parameters) counts as degenerate.
    degenerate_sq: f32,
    // Corners relative to the origin: S(0,0), S(1,0), S(0,1), S(1,1).
    c00_x: f32, c00_y: f32, c00_z: f32,
    c10_x: f32, c10_y: f32, c10_z: f32,
    c01_x: f32, c01_y: f32, c01_z: f32,
    c11_x: f32, c11_y: f32, c11_z: f32,
    // The host's f64 normals at those corners (grid_common.wgsl's fallback_normal).
    n00_x: f32, n00_y: f32, n00_z: f32,
    n10_x: f32, n10_y: f32, n10_z: f32,
    n01_x: f32, n01_y: f32, n01_z: f32,
    n11_x: f32, n11_y: f32, n11_z: f32,
    grid_u: u32, grid_v: u32,
    // Where the patch's vertices and indices start in this chunk's buffers, and the mesh
    // index of its first vertex (what its triangles refer to).
    first_vertex: u32, first_index: u32, mesh_vertex: u32,
    // Its boundary samples: S(u,0) at grid_u columns, then S(u,1), then S(0,v) at grid_v
    // rows, then S(1,v) (units of samples).
    first_sample: u32,
    // Its blend table: [α, 1 − α, α′, α″] per column, then per row (f32 units).
    blend_table: u32,
    pad: u32,
}

@group(0) @binding(0) var<storage, read> jobs: array<CoonsJob>;
// Three vec4 per boundary sample (curves.wgsl): (position, 0), (C′, 0), (C″, 0).
@group(0) @binding(1) var<storage, read> samples: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> blends: array<f32>;
// Two vec4 per vertex: (position xyz, normal x), (normal yz, uv) — tessellate.wgsl's layout.
@group(0) @binding(3) var<storage, read_write> vertices: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> indices: array<u32>;

const WORKGROUP: u32 = 64u;

// One order of derivative of the Coons formula: (f, g) are F₀, F₁ = 1 − α (or their
// derivatives) at u and at v; the boundaries' values (or derivatives) at u and at v.
fn coons_term(job: CoonsJob, fu: f32, gu: f32, fv: f32, gv: f32,
              v0: vec3<f32>, v1: vec3<f32>, u0: vec3<f32>, u1: vec3<f32>) -> vec3<f32> {
    let c00 = vec3<f32>(job.c00_x, job.c00_y, job.c00_z);
    let c10 = vec3<f32>(job.c10_x, job.c10_y, job.c10_z);
    let c01 = vec3<f32>(job.c01_x, job.c01_y, job.c01_z);
    let c11 = vec3<f32>(job.c11_x, job.c11_y, job.c11_z);
    return fv * v0 + gv * v1 + fu * u0 + gu * u1
        - (fu * fv * c00 + gu * fv * c10 + fu * gv * c01 + gu * gv * c11);
}

@compute @workgroup_size(64)
fn blend_coons(@builtin(global_invocation_id) gid: vec3<u32>,
               @builtin(num_workgroups) groups: vec3<u32>) {
    let index = gid.x + gid.y * groups.x * WORKGROUP;
    let count = arrayLength(&jobs);
    let last = jobs[count - 1u];
    if (index >= last.first_vertex + last.grid_u * last.grid_v) { return; }
    var lo = 0u;
    var hi = count - 1u;
    while (lo < hi) {
        let mid = (lo + hi + 1u) / 2u;
        if (jobs[mid].first_vertex <= index) { lo = mid; } else { hi = mid - 1u; }
    }
    let job = jobs[lo];
    let nu = job.grid_u;
    let nv = job.grid_v;
    let i = (index - job.first_vertex) % nu;
    let j = (index - job.first_vertex) / nu;
    // Boundary samples (3 vec4 each): S(u,0), S(u,1) at column i; S(0,v), S(1,v) at row j.
    let v0 = 3u * (job.first_sample + i);
    let v1 = 3u * (job.first_sample + nu + i);
    let u0 = 3u * (job.first_sample + 2u * nu + j);
    let u1 = 3u * (job.first_sample + 2u * nu + nv + j);
    let bu = job.blend_table + 4u * i;
    let bv = job.blend_table + 4u * (nu + j);
    let a = blends[bu];
    let ca = blends[bu + 1u];
    let b = blends[bv];
    let cb = blends[bv + 1u];
    let s = coons_term(job, a, ca, b, cb,
        samples[v0].xyz, samples[v1].xyz, samples[u0].xyz, samples[u1].xyz);
    let au = blends[bu + 2u];
    let bv1 = blends[bv + 2u];
    let su = coons_term(job, au, -au, b, cb,
        samples[v0 + 1u].xyz, samples[v1 + 1u].xyz, samples[u0].xyz, samples[u1].xyz);
    let sv = coons_term(job, a, ca, bv1, -bv1,
        samples[v0].xyz, samples[v1].xyz, samples[u0 + 1u].xyz, samples[u1 + 1u].xyz);
    let u = f32(i) / f32(nu - 1u);
    let v = f32(j) / f32(nv - 1u);
    var normal = cross(su, sv);
    if (dot(normal, normal) <= job.degenerate_sq) {
        // The limit toward the centre of [0, 1]² (grid_common.wgsl).
        let auu = blends[bu + 3u];
        let bvv = blends[bv + 3u];
        let suu = coons_term(job, auu, -auu, b, cb,
            samples[v0 + 2u].xyz, samples[v1 + 2u].xyz, samples[u0].xyz, samples[u1].xyz);
        let suv = coons_term(job, au, -au, bv1, -bv1,
            samples[v0 + 1u].xyz, samples[v1 + 1u].xyz, samples[u0 + 1u].xyz, samples[u1 + 1u].xyz);
        let svv = coons_term(job, a, ca, bvv, -bvv,
            samples[v0].xyz, samples[v1].xyz, samples[u0 + 2u].xyz, samples[u1 + 2u].xyz);
        let corners = array<vec3<f32>, 4>(
            vec3<f32>(job.n00_x, job.n00_y, job.n00_z), vec3<f32>(job.n10_x, job.n10_y, job.n10_z),
            vec3<f32>(job.n01_x, job.n01_y, job.n01_z), vec3<f32>(job.n11_x, job.n11_y, job.n11_z));
        normal = first_order_limit_normal(su, sv, suu, suv, svv, vec2<f32>(1.0), vec2<f32>(u, v),
                                          job.degenerate_sq, fallback_normal(corners, i, j, nu, nv));
    }
    normal = normalize(normal);
    let origin = vec3<f32>(job.origin_x, job.origin_y, job.origin_z);
    vertices[2u * index] = vec4<f32>(s + origin, normal.x);
    vertices[2u * index + 1u] = vec4<f32>(normal.yz, u, v);
    if (i + 1u < nu && j + 1u < nv) {
        let triangles = cell_triangles(job.mesh_vertex + j * nu + i, nu);
        let out = job.first_index + 6u * (j * (nu - 1u) + i);
        for (var k = 0u; k < 6u; k++) {
            indices[out + k] = triangles[k];
        }
    }
}
