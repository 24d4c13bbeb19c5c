//! Opaque geometry as triangles: the ground square and the boxes.

use glam::Vec3;

use super::gpu_data::OpaqueVertex;
use crate::scene::Scene;

/// Triangle-list vertices for the scene's ground and boxes.
pub fn opaque_mesh(scene: &Scene) -> Vec<OpaqueVertex> {
    let mut out = Vec::new();
    let g = &scene.ground;
    let h = g.size_m * 0.5;
    let y = g.height_m;
    quad(
        &mut out,
        [
            Vec3::new(-h, y, h),
            Vec3::new(h, y, h),
            Vec3::new(h, y, -h),
            Vec3::new(-h, y, -h),
        ],
        Vec3::Y,
        g.albedo,
    );
    for b in &scene.boxes {
        let lo = b.center - b.size * 0.5;
        let hi = b.center + b.size * 0.5;
        let c = |x: bool, y: bool, z: bool| {
            Vec3::new(
                if x { hi.x } else { lo.x },
                if y { hi.y } else { lo.y },
                if z { hi.z } else { lo.z },
            )
        };
        // Each face counter-clockwise seen from outside.
        let faces = [
            (
                [
                    c(true, false, true),
                    c(true, false, false),
                    c(true, true, false),
                    c(true, true, true),
                ],
                Vec3::X,
            ),
            (
                [
                    c(false, false, false),
                    c(false, false, true),
                    c(false, true, true),
                    c(false, true, false),
                ],
                Vec3::NEG_X,
            ),
            (
                [
                    c(false, true, true),
                    c(true, true, true),
                    c(true, true, false),
                    c(false, true, false),
                ],
                Vec3::Y,
            ),
            (
                [
                    c(false, false, false),
                    c(true, false, false),
                    c(true, false, true),
                    c(false, false, true),
                ],
                Vec3::NEG_Y,
            ),
            (
                [
                    c(false, false, true),
                    c(true, false, true),
                    c(true, true, true),
                    c(false, true, true),
                ],
                Vec3::Z,
            ),
            (
                [
                    c(true, false, false),
                    c(false, false, false),
                    c(false, true, false),
                    c(true, true, false),
                ],
                Vec3::NEG_Z,
            ),
        ];
        for (corners, normal) in faces {
            quad(&mut out, corners, normal, b.albedo);
        }
    }
    out
}

/// A pipeline drawing [`opaque_mesh`]'s triangles (`vs_main`, `fs_main` of `module`) with depth
/// writes and a `Less` test into `depth_format`, culling `cull`: the opaque pass into the frame
/// (back faces culled) and the occluders' depth map from the light (front faces culled).
pub fn mesh_pipeline(
    device: &wgpu::Device,
    label: &str,
    module: &wgpu::ShaderModule,
    layout: &wgpu::PipelineLayout,
    cull: wgpu::Face,
    depth_format: wgpu::TextureFormat,
    targets: &[Option<wgpu::ColorTargetState>],
) -> wgpu::RenderPipeline {
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &[Some(OpaqueVertex::LAYOUT)],
        },
        primitive: wgpu::PrimitiveState {
            cull_mode: Some(cull),
            ..Default::default()
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: depth_format,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
            targets,
        }),
        multiview_mask: None,
        cache: None,
    })
}

fn quad(out: &mut Vec<OpaqueVertex>, corners: [Vec3; 4], normal: Vec3, albedo: Vec3) {
    for i in [0, 1, 2, 0, 2, 3] {
        out.push(OpaqueVertex {
            position: corners[i].to_array(),
            normal: normal.to_array(),
            albedo: albedo.to_array(),
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn faces_wind_counter_clockwise_around_their_normals() {
        let mut scene = Scene::thesis_plume();
        scene.boxes.truncate(1);
        let mesh = opaque_mesh(&scene);
        assert_eq!(mesh.len(), 6 + 36);
        for tri in mesh.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|i| Vec3::from(tri[i].position));
            let n = (b - a).cross(c - a).normalize();
            assert!(n.dot(Vec3::from(tri[0].normal)) > 0.99);
        }
    }
}
