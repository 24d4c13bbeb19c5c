//! The viewer's orbit camera: yaw, pitch and distance around a target point, converted to and
//! from the scene's camera (position + target), so the scene file stays the one source of truth.

use glam::Vec3;

use smokeshadow_core::scene::Camera;

/// Spherical coordinates of the eye around the target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orbit {
    pub target: Vec3,
    /// Radians around +y, 0 looking along -z.
    pub yaw: f32,
    /// Radians above the horizon, within ±(π/2 − 0.01).
    pub pitch: f32,
    pub distance_m: f32,
}

const PITCH_LIMIT: f32 = std::f32::consts::FRAC_PI_2 - 0.01;

impl Orbit {
    /// The orbit that reproduces `camera`.
    pub fn from_camera(camera: &Camera) -> Self {
        let offset = camera.position - camera.target;
        let distance_m = offset.length().max(1e-3);
        let dir = offset / distance_m;
        Self {
            target: camera.target,
            yaw: dir.x.atan2(dir.z),
            pitch: dir
                .y
                .clamp(-1.0, 1.0)
                .asin()
                .clamp(-PITCH_LIMIT, PITCH_LIMIT),
            distance_m,
        }
    }

    /// The eye position.
    pub fn position(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        self.target + Vec3::new(sy * cp, sp, cy * cp) * self.distance_m
    }

    /// Writes the orbit into `camera` (position and target; the lens is left alone).
    pub fn apply(&self, camera: &mut Camera) {
        camera.position = self.position();
        camera.target = self.target;
    }

    /// Rotates by a pointer drag of `dx`, `dy` pixels.
    pub fn orbit(&mut self, dx: f32, dy: f32) {
        const RADIANS_PER_PX: f32 = 0.008;
        self.yaw -= dx * RADIANS_PER_PX;
        self.pitch = (self.pitch + dy * RADIANS_PER_PX).clamp(-PITCH_LIMIT, PITCH_LIMIT);
    }

    /// Moves the target in the view plane by a drag of `dx`, `dy` pixels of a viewport
    /// `height_px` tall seen through a vertical field of view `fov_y_deg`.
    pub fn pan(&mut self, dx: f32, dy: f32, height_px: f32, fov_y_deg: f32) {
        let forward = (self.target - self.position()).normalize();
        let right = forward.cross(Vec3::Y).normalize_or(Vec3::X);
        let up = right.cross(forward);
        let metres_per_px =
            2.0 * self.distance_m * (fov_y_deg.to_radians() * 0.5).tan() / height_px.max(1.0);
        self.target += (-right * dx + up * dy) * metres_per_px;
    }

    /// Zooms by `steps` (positive: closer), 10% per step.
    pub fn zoom(&mut self, steps: f32) {
        self.distance_m = (self.distance_m * 0.9f32.powf(steps)).clamp(0.5, 500.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_orbit_round_trips_the_scene_camera() {
        let mut camera = smokeshadow_core::scene::Scene::thesis_plume().camera;
        let orbit = Orbit::from_camera(&camera);
        let before = camera.position;
        orbit.apply(&mut camera);
        assert!(
            (camera.position - before).length() < 1e-4,
            "{} vs {before}",
            camera.position
        );
    }

    #[test]
    fn orbiting_keeps_the_distance_and_zooming_changes_it() {
        let camera = smokeshadow_core::scene::Scene::thesis_plume().camera;
        let mut orbit = Orbit::from_camera(&camera);
        let d = orbit.distance_m;
        orbit.orbit(120.0, -40.0);
        assert!((orbit.position().distance(orbit.target) - d).abs() < 1e-3);
        orbit.zoom(2.0);
        assert!((orbit.distance_m - d * 0.81).abs() < 1e-3);
        let target = orbit.target;
        orbit.pan(100.0, 0.0, 768.0, 40.0);
        assert!(orbit.target.distance(target) > 0.0);
        assert!(
            (orbit.target.y - target.y).abs() < 1e-4,
            "a horizontal drag pans sideways"
        );
    }
}
