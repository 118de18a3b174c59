// Surfaces evaluated at scattered parameters, in f32: the GPU executor of the vertices of
// trimmed faces' and shells' plans (src/gpu/points.rs). The host cuts each surface into its
// rational Bezier cells (nets relative to each cell's centre, with their differences, as the
// view-dependent kernel reads them) and gives every sample its cell and local (s, t); one
// invocation per sample writes the point relative to its cell's centre (the host adds the
// centre in f64) and the unit normal. grid_common.wgsl and bezier_cell.wgsl are prepended.
// Only core WGSL and f32: it runs on WebGPU as well as native adapters.

// Cells of CELL_WORDS words: the words bezier_cell.wgsl names (CELL_DEGENERATE,
// CELL_DEGREE_U, CELL_DEGREE_V, CELL_NET, CELL_CORNER_NORMALS..+12), the others unused.
@group(0) @binding(0) var<storage, read> cells: array<u32>;
@group(0) @binding(1) var<storage, read> points: array<vec4<f32>>;
// Per sample: (cell (bits), s, t, 0).
@group(0) @binding(2) var<storage, read> samples: array<vec4<f32>>;
// Two vec4 per sample: (point − cell centre, normal x), (normal y, normal z, 0, 0).
@group(0) @binding(3) var<storage, read_write> results: array<vec4<f32>>;

const CELL_WORDS: u32 = 36u;
const WORKGROUP: u32 = 64u;

fn cell_u32(c: u32, word: u32) -> u32 { return cells[c * CELL_WORDS + word]; }
fn cell_f32(c: u32, word: u32) -> f32 { return bitcast<f32>(cells[c * CELL_WORDS + word]); }

@compute @workgroup_size(64)
fn evaluate_samples(@builtin(global_invocation_id) gid: vec3<u32>,
                    @builtin(num_workgroups) groups: vec3<u32>) {
    let index = gid.x + gid.y * groups.x * WORKGROUP;
    if (index >= arrayLength(&samples)) { return; }
    let sample = samples[index];
    let evaluated = evaluate_cell(bitcast<u32>(sample.x), sample.y, sample.z);
    results[2u * index] = vec4<f32>(evaluated.local, evaluated.normal.x);
    results[2u * index + 1u] = vec4<f32>(evaluated.normal.yz, 0.0, 0.0);
}
