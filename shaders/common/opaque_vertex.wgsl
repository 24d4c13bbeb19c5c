// A vertex of the opaque geometry (ground and boxes), as the opaque pass and the occluders'
// depth map read it. Keep in sync with `OpaqueVertex` in src/frame/gpu_data.rs (its buffer
// layout, `OpaqueVertex::LAYOUT`).
struct OpaqueVertex {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) albedo: vec3<f32>,
};
