// The transmittance probe: evaluates the active technique's `shadow_transmittance` (the same
// function the lighting shaders call) at a list of world points: the smoke's T, and for a point
// whose w is 1 the light's whole visibility as the lighting computes it, T times the opaque
// occluders' `occluder_visibility` (the reference's self-check, src/render/reference_check.rs).
#import common/lighting.wgsl
#import shadow_technique
#import occluders

// xyz: world point (m); w: 1 to include the opaque occluders, else 0.
@group(2) @binding(0) var<storage, read> probe_points: array<vec4<f32>>;
@group(2) @binding(1) var<storage, read_write> probe_results: array<f32>;

@compute @workgroup_size(64)
fn probe_main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= arrayLength(&probe_results) {
        return;
    }
    // A point light's faces are probed in turn, each writing the points in its face.
    let point = probe_points[id.x];
    let p = point.xyz;
    if in_light_face(p) {
        var t = shadow_transmittance(p);
        if point.w > 0.5 {
            t *= occluder_visibility(p);
        }
        probe_results[id.x] = t;
    }
}
