// The transmittance probe: evaluates the active technique's `shadow_transmittance` (the same
// function the lighting shaders call) at a list of world points: the smoke's T, without the
// opaque occluders' visibility.
#import common/lighting.wgsl
#import shadow_technique

// xyz: world point (m); w unused.
@group(2) @binding(0) var<storage, read> probe_points: array<vec4<f32>>;
@group(2) @binding(1) var<storage, read_write> probe_results: array<f32>;

@compute @workgroup_size(64)
fn probe_main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= arrayLength(&probe_results) {
        return;
    }
    // A point light's faces are probed in turn, each writing the points in its face.
    let p = probe_points[id.x].xyz;
    if in_light_face(p) {
        probe_results[id.x] = shadow_transmittance(p);
    }
}
