//! CPU-side mirrors of the WGSL structs, `#[repr(C)]` + `Pod`, with explicit padding.

use bytemuck::{Pod, Zeroable};

/// Keep in sync with `Frame` in shaders/common/frame.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct FrameUniforms {
    pub clip_from_world: [[f32; 4]; 4],
    pub world_from_clip: [[f32; 4]; 4],
    pub light_clip_from_world: [[f32; 4]; 4],
    /// The light's projection for rasterising the occluders' depth map (same view and field of
    /// view as `light_clip_from_world`, near/far around the opaque geometry).
    pub occluder_clip_from_world: [[f32; 4]; 4],
    /// The inverse of `light_clip_from_world`: a light-space texel's ray (the volume's build).
    pub world_from_light_clip: [[f32; 4]; 4],
    /// xyz eye position, w near clip (m).
    pub camera_pos: [f32; 4],
    /// xyz unit view direction, w far clip (m).
    pub camera_forward: [f32; 4],
    /// width, height, 1/width, 1/height.
    pub viewport: [f32; 4],
    /// xyz light position, w cos(cone half-angle).
    pub light_pos: [f32; 4],
    /// xyz unit cone axis, w cos(inner angle).
    pub light_dir: [f32; 4],
    /// rgb colour x intensity, w Henyey-Greenstein g.
    pub light_radiance: [f32; 4],
    /// near, far, 1/(far - near) of the smoke's radial distance from the light; w the cube
    /// face of a point light's light space, -1 for a spotlight.
    pub light_depth: [f32; 4],
    /// rgb ambient, w exposure.
    pub ambient: [f32; 4],
    /// rgb background.
    pub background: [f32; 4],
    /// The occluders' depth map: far distance (m), 1 / far, side (texels), number of boxes.
    pub occluders: [f32; 4],
    /// Ground height (m), half the ground's side (m), the exact occluder test's epsilon (m,
    /// [`super::occluders::epsilon_m`]), unused.
    pub ground: [f32; 4],
    /// The density volume's placement and the frame's marches (`crate::medium::frame`).
    pub grid: crate::medium::gpu_grid::GridParams,
}

/// One box of the opaque geometry for the analytic occluder test (`common/occluders_exact.wgsl`):
/// its corners, world metres (w unused).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct OccluderBox {
    pub min: [f32; 4],
    pub max: [f32; 4],
}

/// Vertices drawn per billboard (a quad as two triangles). Keep in sync with `BILLBOARD_VERTICES` in
/// shaders/common/particle.wgsl.
pub const BILLBOARD_VERTICES: u32 = 6;

/// One particle as the GPU sees it. Keep in sync with `ParticleIn` in
/// shaders/common/particle.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct ParticleInstance {
    /// xyz centre (m), w radius (m).
    pub center_radius: [f32; 4],
    /// rgb albedo, a extinction τ (1/m).
    pub albedo_density: [f32; 4],
}

impl ParticleInstance {
    pub const LAYOUT: wgpu::VertexBufferLayout<'static> = wgpu::VertexBufferLayout {
        array_stride: std::mem::size_of::<ParticleInstance>() as u64,
        step_mode: wgpu::VertexStepMode::Instance,
        attributes: &wgpu::vertex_attr_array![0 => Float32x4, 1 => Float32x4],
    };

    pub fn from_particle(p: &crate::sim::Particle) -> Self {
        Self {
            center_radius: p.position.extend(p.radius_m).to_array(),
            albedo_density: p.albedo.extend(p.density_per_m).to_array(),
        }
    }
}

/// A vertex of the opaque geometry. Keep in sync with `OpaqueVertex` in
/// shaders/common/opaque_vertex.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct OpaqueVertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub albedo: [f32; 3],
}

impl OpaqueVertex {
    pub const LAYOUT: wgpu::VertexBufferLayout<'static> = wgpu::VertexBufferLayout {
        array_stride: std::mem::size_of::<OpaqueVertex>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x3],
    };
}

/// The WGSL structs mirrored here (vertex inputs are laid out by their buffer layouts instead).
pub fn layouts() -> Vec<crate::gpu::MirrorLayout> {
    vec![
        crate::mirror_layout!(
            FrameUniforms,
            "common/frame.wgsl",
            "Frame",
            [
                clip_from_world,
                world_from_clip,
                light_clip_from_world,
                occluder_clip_from_world,
                world_from_light_clip,
                camera_pos,
                camera_forward,
                viewport,
                light_pos,
                light_dir,
                light_radiance,
                light_depth,
                ambient,
                background,
                occluders,
                ground,
                grid,
            ]
        ),
        crate::mirror_layout!(
            OccluderBox,
            "common/occluders_exact.wgsl",
            "OccluderBox",
            [min, max]
        ),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_match_the_wgsl_layouts() {
        // 5 mat4x4 + 11 vec4 + the grid's parameters (a mat4x4 and 6 vec4).
        assert_eq!(std::mem::size_of::<FrameUniforms>(), 5 * 64 + 11 * 16 + 160);
        assert_eq!(std::mem::size_of::<ParticleInstance>(), 32);
        assert_eq!(std::mem::size_of::<OpaqueVertex>(), 36);
    }
}
