// The frame's density volume (src/medium/frame.rs): `frame.grid` and `grid_density` in group 0
// (shaders/common/frame.wgsl), so that every pass can read it: the eye's march, the techniques'
// builds and lookups. A scene without a volume has dims of 0 and one zero voxel.
#import common/frame.wgsl

fn medium_present() -> bool {
    return grid_params().dims.x > 0u;
}

// Optical depth of the volume between world points `a` and `b` by `steps` midpoint steps
// (0 without a volume).
fn medium_optical_depth(a: vec3<f32>, b: vec3<f32>, steps: u32) -> f32 {
    if !medium_present() {
        return 0.0;
    }
    return grid_optical_depth(a, b, steps);
}

// As the reference takes it: a shape's in closed form, a grid's by `steps` midpoint steps
// (grid_reference_optical_depth; 0 without a volume).
fn medium_reference_optical_depth(a: vec3<f32>, b: vec3<f32>, steps: u32) -> f32 {
    if !medium_present() {
        return 0.0;
    }
    return grid_reference_optical_depth(a, b, steps);
}
