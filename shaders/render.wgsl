// Headless preview rendering of tessellated meshes (src/render.rs): two-sided Lambert shading
// of the surfaces, flat-coloured lines for the wireframe and control-net overlays.

// Mirrors src/render.rs `Frame`.
struct Frame {
    view_projection: mat4x4<f32>,
    eye: vec4<f32>,
    light: vec4<f32>,
    surface_colour: vec4<f32>,
    line_colour: vec4<f32>,
    net_colour: vec4<f32>,
}

@group(0) @binding(0) var<uniform> frame: Frame;

struct Shaded {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
}

@vertex
fn vs_surface(@location(0) position: vec3<f32>, @location(1) normal: vec3<f32>, @location(2) uv: vec2<f32>) -> Shaded {
    return Shaded(frame.view_projection * vec4<f32>(position, 1.0), position, normal);
}

@fragment
fn fs_surface(input: Shaded) -> @location(0) vec4<f32> {
    // Surfaces have no thickness: shade the side facing the camera.
    var n = normalize(input.normal);
    if (dot(n, frame.eye.xyz - input.world) < 0.0) {
        n = -n;
    }
    let key = max(dot(n, normalize(frame.light.xyz)), 0.0);
    let head = max(dot(n, normalize(frame.eye.xyz - input.world)), 0.0);
    let light = 0.15 + 0.6 * key + 0.3 * head;
    return vec4<f32>(frame.surface_colour.rgb * light, 1.0);
}

@vertex
fn vs_line(@location(0) position: vec3<f32>) -> @builtin(position) vec4<f32> {
    return frame.view_projection * vec4<f32>(position, 1.0);
}

@fragment
fn fs_line() -> @location(0) vec4<f32> {
    return frame.line_colour;
}

@fragment
fn fs_net() -> @location(0) vec4<f32> {
    return frame.net_colour;
}
