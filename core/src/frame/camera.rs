//! The camera's matrices, from the scene's camera and the output size.

use glam::{Mat4, Vec3};

use crate::scene::Scene;

/// The camera's matrices and frame.
#[derive(Clone, Copy, Debug)]
pub struct CameraMatrices {
    pub position: Vec3,
    pub forward: Vec3,
    pub view_from_world: Mat4,
    pub clip_from_view: Mat4,
}

impl CameraMatrices {
    pub fn new(scene: &Scene, width: u32, height: u32) -> Self {
        let cam = &scene.camera;
        let forward = (cam.target - cam.position).normalize();
        let up = if forward.y.abs() > 0.999 {
            Vec3::Z
        } else {
            Vec3::Y
        };
        Self {
            position: cam.position,
            forward,
            view_from_world: Mat4::look_at_rh(cam.position, cam.target, up),
            clip_from_view: Mat4::perspective_rh(
                cam.fov_y_deg.to_radians(),
                width as f32 / height as f32,
                cam.near_m,
                cam.far_m,
            ),
        }
    }

    pub fn clip_from_world(&self) -> Mat4 {
        self.clip_from_view * self.view_from_world
    }

    /// Pixel coordinates (x right, y down, pixel centres at +0.5) of a world point, if in front.
    pub fn project_to_pixel(&self, p: Vec3, width: u32, height: u32) -> Option<glam::Vec2> {
        let clip = self.clip_from_world() * p.extend(1.0);
        if clip.w <= 0.0 {
            return None;
        }
        let ndc = clip.truncate() / clip.w;
        Some(glam::Vec2::new(
            (ndc.x * 0.5 + 0.5) * width as f32,
            (0.5 - ndc.y * 0.5) * height as f32,
        ))
    }
}
