//! The spotlight's view of the smoke, shared by every technique.
//!
//! The shadow map covers the spotlight's cone with a perspective projection from the light. The
//! depth coordinate is the *radial distance from the light*, so each shadow-map texel's light
//! ray crosses a particle along an exact chord and the slices/layers are concentric shells; it is
//! fitted tightly to the particles every frame (nearest sphere surface to farthest), as the
//! thesis' opacity maps require.
//!
//! A point light has six light spaces, the faces of a cube around it ([`LightSpace::faces`]):
//! each a 90° perspective (widened by [`CUBE_FACE_MARGIN`] so that filtered lookups at a face's
//! edge read texels of that face) along one axis direction, all sharing the same radial bounds,
//! so the slices of a layered map are the same spherical shells on every face. A point belongs
//! to the face of its dominant axis ([`cube_face`], mirrored by `cube_face` in
//! shaders/common/lighting.wgsl).

use glam::{Mat4, Vec3};

use crate::scene::{LightKind, Spotlight};
use crate::sim::Particle;

/// The light's projection and the frame's depth bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSpace {
    /// The spotlight's position, world metres.
    pub position: Vec3,
    /// Perspective projection x view of the spotlight covering its cone.
    pub clip_from_world: Mat4,
    /// The view part alone (right-handed: the light looks down −z).
    pub view_from_world: Mat4,
    /// tan of half the projection's field of view: a view-space point (x, y, z) lands at
    /// NDC (x, y) / (−z · tan_half_fov).
    pub tan_half_fov: f32,
    /// Radial distance from the light to the nearest particle surface, metres.
    pub near_m: f32,
    /// Radial distance from the light to the farthest particle surface, metres.
    pub far_m: f32,
    /// The largest particle radius this frame, metres (0 without particles).
    pub max_radius_m: f32,
    /// The mean particle radius and the mean radial distance of the particles from the light,
    /// metres (0 without particles): the typical footprint `exact` sizes its tiles by.
    pub mean_radius_m: f32,
    pub mean_dist_m: f32,
    /// The cube face (0..6: +x, −x, +y, −y, +z, −z) of a point light's light space; `None`
    /// for a spotlight's.
    pub face: Option<u8>,
}

/// tan of half a cube face's field of view: 1 (90°) plus 2%, about five texels of a 512² map
/// on each side, so the bilinear and filtered taps of a point on the face's edge stay inside it.
pub const CUBE_FACE_MARGIN: f32 = 1.02;

/// Names of the cube faces, in [`cube_face`]'s order.
pub const CUBE_FACE_NAMES: [&str; 6] = ["+x", "-x", "+y", "-y", "+z", "-z"];

/// Axis direction and up vector of each cube face.
const CUBE_FACES: [(Vec3, Vec3); 6] = [
    (Vec3::X, Vec3::NEG_Y),
    (Vec3::NEG_X, Vec3::NEG_Y),
    (Vec3::Y, Vec3::Z),
    (Vec3::NEG_Y, Vec3::NEG_Z),
    (Vec3::Z, Vec3::NEG_Y),
    (Vec3::NEG_Z, Vec3::NEG_Y),
];

/// The cube face a direction from a point light falls in: its dominant axis (ties to x, then
/// y), positive or negative. Keep in sync with `cube_face` in shaders/common/lighting.wgsl.
pub fn cube_face(d: Vec3) -> u8 {
    let a = d.abs();
    if a.x >= a.y && a.x >= a.z {
        if d.x >= 0.0 { 0 } else { 1 }
    } else if a.y >= a.z {
        if d.y >= 0.0 { 2 } else { 3 }
    } else if d.z >= 0.0 {
        4
    } else {
        5
    }
}

impl LightSpace {
    /// The light spaces of `light` this frame: the spotlight's one, or a point light's six
    /// cube faces in [`cube_face`]'s order.
    pub fn faces(light: &Spotlight, particles: &[Particle]) -> Vec<Self> {
        Self::faces_with(light, particles, None)
    }

    /// [`LightSpace::faces`] of a scene that also holds a density volume within the world box
    /// `volume` (min, max): the radial bounds enclose the box too.
    pub fn faces_with(
        light: &Spotlight,
        particles: &[Particle],
        volume: Option<(Vec3, Vec3)>,
    ) -> Vec<Self> {
        let mut faces: Vec<Self> = match light.kind {
            LightKind::Spot => vec![Self::fit(light, particles)],
            LightKind::Point => (0..6)
                .map(|f| Self::fit_face(light, f, particles))
                .collect(),
        };
        if let Some((lo, hi)) = volume {
            let (near, far) = crate::medium::frame::box_distances(light.position, lo, hi);
            for face in &mut faces {
                face.enclose(near, far, particles.is_empty());
            }
        }
        faces
    }

    /// Widens the radial bounds to [`near`, `far`] as well (replacing them when there are no
    /// particles), and the projection's planes with them.
    fn enclose(&mut self, near: f32, far: f32, alone: bool) {
        let (old_near, old_far) = match alone {
            true => (f32::INFINITY, 0.0),
            false => (self.near_m, self.far_m),
        };
        let far = far.max(old_far).max(f32::MIN_POSITIVE);
        let near = near.min(old_near).max(1e-4 * far);
        let far = far.max(near * (1.0 + 1e-4));
        let fov = 2.0 * self.tan_half_fov.atan();
        let z_near = (0.5 * near * (0.5 * fov).cos()).max(1e-6 * far);
        let proj = Mat4::perspective_rh(fov, 1.0, z_near, 2.0 * far);
        self.clip_from_world = proj * self.view_from_world;
        self.near_m = near;
        self.far_m = far;
    }

    /// The spotlight's light space: its cone (the point light's faces: [`LightSpace::faces`]).
    pub fn fit(light: &Spotlight, particles: &[Particle]) -> Self {
        let axis = (light.target - light.position).normalize();
        let helper = if axis.y.abs() > 0.99 {
            Vec3::X
        } else {
            Vec3::Y
        };
        let view = Mat4::look_at_rh(light.position, light.target, helper);
        // A small margin so the penumbra edge is inside the map.
        let fov = (2.0 * light.cone_angle_deg.to_radians() * 1.04).min(170f32.to_radians());
        Self::with_view(light.position, view, fov, None, particles)
    }

    /// Cube face `face` of a point light at `light.position`.
    fn fit_face(light: &Spotlight, face: u8, particles: &[Particle]) -> Self {
        let (axis, up) = CUBE_FACES[usize::from(face)];
        let view = Mat4::look_at_rh(light.position, light.position + axis, up);
        let fov = 2.0 * CUBE_FACE_MARGIN.atan();
        Self::with_view(light.position, view, fov, Some(face), particles)
    }

    /// A light space looking through `view` with a square `fov` (radians), its radial bounds
    /// fitted to every particle (the same on every face of a point light).
    fn with_view(
        position: Vec3,
        view: Mat4,
        fov: f32,
        face: Option<u8>,
        particles: &[Particle],
    ) -> Self {
        let (mut near, mut far, mut max_radius) = (f32::INFINITY, 0.0f32, 0.0f32);
        let (mut radius_sum, mut dist_sum) = (0.0f64, 0.0f64);
        for p in particles {
            let dist = p.position.distance(position);
            near = near.min(dist - p.radius_m);
            far = far.max(dist + p.radius_m);
            max_radius = max_radius.max(p.radius_m);
            radius_sum += f64::from(p.radius_m);
            dist_sum += f64::from(dist);
        }
        let count = particles.len().max(1) as f64;
        if !near.is_finite() {
            (near, far) = (1.0, 2.0);
        }
        // Every bound is relative to the smoke's own distance from the light, so that a 1 cm
        // puff and a 1 km cloud are fitted alike: a light inside the smoke starts its depth
        // range at 1e-4 of the farthest surface instead of at 0.
        let far = far.max(f32::MIN_POSITIVE);
        let near = near.max(1e-4 * far);
        let far = far.max(near * (1.0 + 1e-4));
        // The projection only clips what the builds rasterise (their depth is radial, computed
        // in the shaders): no billboard of the smoke may be cut. A light-facing billboard's
        // corners lie at least `near` from the light, and at a view depth of at least
        // near · cos(fov/2) (one at the edge of the field of view); half that is the near plane.
        // They lie within twice the farthest surface (r·√2 beyond a centre), the far plane.
        let z_near = (0.5 * near * (0.5 * fov).cos()).max(1e-6 * far);
        let proj = Mat4::perspective_rh(fov, 1.0, z_near, 2.0 * far);
        Self {
            position,
            clip_from_world: proj * view,
            view_from_world: view,
            tan_half_fov: (0.5 * fov).tan(),
            near_m: near,
            far_m: far,
            max_radius_m: max_radius,
            mean_radius_m: (radius_sum / count) as f32,
            mean_dist_m: (dist_sum / count) as f32,
            face,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_enclose_every_sphere() {
        let light = Spotlight {
            position: Vec3::new(0.0, 10.0, 0.0),
            target: Vec3::ZERO,
            ..Spotlight::default()
        };
        let mk = |y: f32, r: f32| Particle {
            position: Vec3::new(0.0, y, 0.0),
            velocity: Vec3::ZERO,
            age_s: 0.0,
            radius_m: r,
            density_per_m: 1.0,
            albedo: Vec3::ONE,
        };
        let ls = LightSpace::fit(&light, &[mk(5.0, 0.5), mk(2.0, 1.0)]);
        assert!((ls.near_m - 4.5).abs() < 1e-5);
        assert!((ls.far_m - 9.0).abs() < 1e-5);
        assert_eq!(ls.max_radius_m, 1.0);
        // The target is at the centre of the shadow map.
        let c = ls.clip_from_world.project_point3(Vec3::new(0.0, 1.0, 0.0));
        assert!(c.x.abs() < 1e-5 && c.y.abs() < 1e-5);
        // The view and tan(fov/2) give the same NDC as the full projection.
        let p = Vec3::new(1.5, 2.0, -0.7);
        let (v, c) = (
            ls.view_from_world.transform_point3(p),
            ls.clip_from_world.project_point3(p),
        );
        let ndc = v.truncate() / (-v.z * ls.tan_half_fov);
        assert!((ndc.x - c.x).abs() < 1e-5 && (ndc.y - c.y).abs() < 1e-5);
        assert!((ls.mean_radius_m - 0.75).abs() < 1e-6);
        assert!((ls.mean_dist_m - 6.5).abs() < 1e-5);
    }
}
