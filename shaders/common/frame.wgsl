// Per-frame uniforms shared by every pass: camera, spotlight and light-space bounds, and the
// scene's density volume (its placement and march settings in `grid`, its voxels in
// `grid_density`; src/medium/frame.rs). Keep in sync with `FrameUniforms` in
// src/frame/gpu_data.rs.
#import medium/grid.wgsl

struct Frame {
    clip_from_world: mat4x4<f32>,
    world_from_clip: mat4x4<f32>,
    light_clip_from_world: mat4x4<f32>,
    // The light's projection for rasterising the opaque occluders' depth map: the same view and
    // field of view as `light_clip_from_world` (so the same map coordinates), with near and far
    // planes around the opaque geometry instead of the smoke.
    occluder_clip_from_world: mat4x4<f32>,
    // The inverse of `light_clip_from_world`: a light-space texel's ray.
    world_from_light_clip: mat4x4<f32>,
    // xyz: eye position (m); w: near clip distance (m).
    camera_pos: vec4<f32>,
    // xyz: unit view direction; w: far clip distance (m).
    camera_forward: vec4<f32>,
    // width, height, 1/width, 1/height of the render target (px).
    viewport: vec4<f32>,
    // xyz: spotlight position (m); w: cos of the cone half-angle (edge of the penumbra).
    light_pos: vec4<f32>,
    // xyz: unit cone axis; w: cos of the inner angle where the penumbra starts.
    light_dir: vec4<f32>,
    // rgb: colour x radiant intensity; w: Henyey-Greenstein g.
    light_radiance: vec4<f32>,
    // Radial distance from the light bounding the smoke this frame:
    // x: near (m), y: far (m), z: 1 / (far - near), w: the cube face (0..6) of a point light's
    // light space, or -1 for a spotlight's (common/lighting.wgsl: `in_light_face`).
    light_depth: vec4<f32>,
    // rgb: ambient radiance; w: exposure.
    ambient: vec4<f32>,
    // rgb: background radiance; w: unused.
    background: vec4<f32>,
    // The opaque occluders (common/occluders_*.wgsl): x: the depth map's far distance from the
    // light (m), y: its inverse, z: the map's side (texels), w: the number of boxes.
    occluders: vec4<f32>,
    // x: ground height (m), y: half the ground square's side (m), z: the length below which the
    // exact occluder test treats a point as on a surface (m, src/frame/occluders.rs: `epsilon_m`);
    // w: unused.
    ground: vec4<f32>,
    // The density volume's placement and the frame's marches (dims 0 without a volume).
    grid: GridParams,
};

@group(0) @binding(0) var<uniform> frame: Frame;
// The density volume's voxels (one zero voxel without a volume). A uniform of its own here
// would crash lavapipe (not a validation error) beside `avsm`'s, so its parameters ride in
// `frame`.
@group(0) @binding(4) var grid_density: texture_3d<f32>;

fn grid_params() -> GridParams {
    return frame.grid;
}
