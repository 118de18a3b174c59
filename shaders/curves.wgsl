// Sampling of rational B-spline curves, in f32: position, first and second derivative.
//
// The host (src/gpu/curves.rs) stores each curve's control points relative to an origin and
// computes its basis values at every sample in f64, in the table layout of tessellate.wgsl;
// one invocation per sample: the homogeneous sums, the quotient rule, the origin added last.
// Only core WGSL and f32: it runs on WebGPU as well as native adapters.

// Mirrors src/gpu/curves.rs `CurveJob`: all scalars, 32 bytes.
struct CurveJob {
    origin_x: f32, origin_y: f32, origin_z: f32,
    degree: u32,
    // Index of the curve's first sample in `samples` (units of samples), and its sample count.
    first_sample: u32, samples: u32,
    // Offsets of its control points (vec4 units) and of its basis table (f32 units).
    points: u32, table: u32,
}

@group(0) @binding(0) var<storage, read> curves: array<CurveJob>;
@group(0) @binding(1) var<storage, read> points: array<vec4<f32>>;
// Per sample: [fraction, span (bits), N_0..N_p, N'_0..N'_p, N''_0..N''_p]: 2 + 3(p+1) floats.
@group(0) @binding(2) var<storage, read> tables: array<f32>;
// Three vec4 per sample: (position, 0), (C′, 0), (C″, 0); derivatives in model units per
// parameter unit (squared).
@group(0) @binding(3) var<storage, read_write> samples: array<vec4<f32>>;

const WORKGROUP: u32 = 64u;

@compute @workgroup_size(64)
fn sample_curves(@builtin(global_invocation_id) gid: vec3<u32>,
                 @builtin(num_workgroups) groups: vec3<u32>) {
    let index = gid.x + gid.y * groups.x * WORKGROUP;
    let count = arrayLength(&curves);
    let last = curves[count - 1u];
    if (index >= last.first_sample + last.samples) { return; }
    // The curve holding this sample: the last one whose first sample is at or before it.
    var lo = 0u;
    var hi = count - 1u;
    while (lo < hi) {
        let mid = (lo + hi + 1u) / 2u;
        if (curves[mid].first_sample <= index) { lo = mid; } else { hi = mid - 1u; }
    }
    let curve = curves[lo];
    let p = curve.degree;
    let entry = curve.table + (index - curve.first_sample) * (2u + 3u * (p + 1u));
    let first_point = curve.points + bitcast<u32>(tables[entry + 1u]) - p;
    var a = vec4<f32>(0.0);
    var a1 = vec4<f32>(0.0);
    var a2 = vec4<f32>(0.0);
    for (var k = 0u; k <= p; k++) {
        let point = points[first_point + k];
        a += tables[entry + 2u + k] * point;
        a1 += tables[entry + 3u + p + k] * point;
        a2 += tables[entry + 4u + 2u * p + k] * point;
    }
    let c = a.xyz / a.w;
    let c1 = (a1.xyz - a1.w * c) / a.w;
    let c2 = (a2.xyz - 2.0 * a1.w * c1 - a2.w * c) / a.w;
    let out = 3u * index;
    samples[out] = vec4<f32>(c + vec3<f32>(curve.origin_x, curve.origin_y, curve.origin_z), 0.0);
    samples[out + 1u] = vec4<f32>(c1, 0.0);
    samples[out + 2u] = vec4<f32>(c2, 0.0);
}
