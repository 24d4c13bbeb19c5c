//! The exact transmittance of the particle model, in closed form, on the CPU (the vello habit:
//! a CPU mirror of what the GPU computes, so tests can tell a build bug from a lookup bug).
//!
//! Each particle is a sphere whose extinction along a ray is τ(1 - d/r), with d the ray's
//! distance from the centre: the density model the spherical billboards and the chord splat
//! use. The light reaching a point p is then
//!
//! T(p) = exp(-Σ_i τ_i (1 - d_i/r_i) ℓ_i(p)),
//!
//! with d_i the distance from particle i's centre to the light ray through p and ℓ_i(p) the part
//! of the chord through sphere i that lies between the light and p. It is exact at any particle
//! count and needs no shadow map. `exact` evaluates the same sum on the GPU through its tile
//! lists; `probe` prints both, and the tests hold them to 1e-5 of each other.
//!
//! The opaque occluders (ground and boxes) are mirrored too ([`occluder_visibility`]): the light
//! either reaches a point past them or not, exactly as `shaders/common/occluders_exact.wgsl`
//! tests it, so [`crate::render::reference_check`] can hold `exact`'s whole lighting to this
//! module.

use glam::{DVec3, Vec3};

use crate::scene::Scene;
use crate::sim::Particle;

/// Whether the light reaches a point past the opaque geometry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Visibility {
    Lit,
    Blocked,
    /// The segment to the light passes within the test's epsilon of an occluder's edge, or the
    /// point lies within it of a surface's plane: f32 on the GPU and f64 here may decide either
    /// way, so a check skips the point.
    KnifeEdge,
}

/// Visibility of the light at `light` from `p` past `scene`'s ground square and boxes, with the
/// GPU test's rules (`shaders/common/occluders_exact.wgsl`): a box hit closer than `epsilon_m`
/// to `p` is `p`'s own surface, and the ground does not shadow a point within `epsilon_m` of
/// its plane (`epsilon_m` is `crate::frame::occluders::epsilon_m`). The test is decided twice,
/// once with every occluder grown by a tenth of `epsilon_m` and once shrunk by it (the self-hit
/// epsilons halved and doubled with them), far more than the GPU's f32 rounding moves an edge:
/// where the two disagree the point is a [`Visibility::KnifeEdge`].
pub fn occluder_visibility(scene: &Scene, light: Vec3, p: Vec3, epsilon_m: f32) -> Visibility {
    let eps = f64::from(epsilon_m);
    let blocked =
        |grow: f64| blocked_by_occluders(scene, light.as_dvec3(), p.as_dvec3(), eps, grow);
    match (blocked(0.1 * eps), blocked(-0.1 * eps)) {
        (true, true) => Visibility::Blocked,
        (false, false) => Visibility::Lit,
        _ => Visibility::KnifeEdge,
    }
}

/// The GPU test in f64, every occluder grown by `grow` (shrunk where negative) and the epsilons
/// scaled to match: the larger occluder comes with the smaller self-hit epsilons.
fn blocked_by_occluders(scene: &Scene, light: DVec3, p: DVec3, eps: f64, grow: f64) -> bool {
    let scale = if grow > 0.0 { 0.5 } else { 2.0 };
    let to_light = light - p;
    let length = to_light.length();
    if length <= 0.0 {
        return false;
    }
    let g = &scene.ground;
    let height = f64::from(g.height_m);
    let below = p.y - height;
    let light_above = light.y - height;
    if below.abs() > eps * scale && below * light_above < 0.0 {
        let q = p + to_light * (below / (below - light_above));
        let half = 0.5 * f64::from(g.size_m) + grow;
        if q.x.abs() <= half && q.z.abs() <= half {
            return true;
        }
    }
    let t_min = eps * scale / length;
    scene.boxes.iter().any(|b| {
        let (c, h) = (
            b.center.as_dvec3(),
            0.5 * b.size.as_dvec3() + DVec3::splat(grow),
        );
        let (lo, hi) = (c - h, c + h);
        let (mut enter, mut exit) = (f64::NEG_INFINITY, f64::INFINITY);
        for axis in 0..3 {
            let d = to_light[axis];
            if d.abs() < 1e-300 {
                if p[axis] < lo[axis] || p[axis] > hi[axis] {
                    return false;
                }
                continue;
            }
            let (t0, t1) = ((lo[axis] - p[axis]) / d, (hi[axis] - p[axis]) / d);
            enter = enter.max(t0.min(t1));
            exit = exit.min(t0.max(t1));
        }
        exit >= enter.max(t_min) && enter <= 1.0
    })
}

/// Optical depth from `light` to `p` through `particles` (metres, 1/m; f64 throughout).
pub fn optical_depth(light: Vec3, p: Vec3, particles: &[Particle]) -> f64 {
    let light = light.as_dvec3();
    let to_p = p.as_dvec3() - light;
    let length = to_p.length();
    if length <= 0.0 {
        return 0.0;
    }
    let dir = to_p / length;
    particles
        .iter()
        .map(|particle| {
            chord_optical_depth(
                light,
                dir,
                length,
                particle.position.as_dvec3(),
                f64::from(particle.radius_m),
                f64::from(particle.density_per_m),
            )
        })
        .sum()
}

/// Transmittance from `light` to `p`: exp(-[`optical_depth`]).
pub fn transmittance(light: Vec3, p: Vec3, particles: &[Particle]) -> f32 {
    transmittance_of(optical_depth(light, p, particles)) as f32
}

/// The optical depth `exact`'s sum saturates at (shaders/shadow/exact.wgsl): beyond it T is
/// below exp(-12) = 6.1e-6, and the light it no longer tells apart from none is at most that
/// fraction of the unshadowed light, under half a step of an 8-bit image unless the unshadowed
/// light is shown over 600 times brighter than white. The walk stops there.
pub const OPTICAL_DEPTH_CUT: f64 = 12.0;

/// T as `exact` takes it from an optical depth: exp(-min(τ, cut)), within exp(-12) = 6.1e-6 of
/// exp(-τ).
pub fn transmittance_of(optical_depth: f64) -> f64 {
    (-optical_depth.min(OPTICAL_DEPTH_CUT)).exp()
}

/// One sphere's contribution along the ray `origin + t dir`, t in [0, length].
fn chord_optical_depth(
    origin: DVec3,
    dir: DVec3,
    length: f64,
    center: DVec3,
    radius: f64,
    tau: f64,
) -> f64 {
    if radius <= 0.0 || tau <= 0.0 {
        return 0.0;
    }
    let oc = center - origin;
    let t_mid = oc.dot(dir);
    let d2 = (oc.length_squared() - t_mid * t_mid).max(0.0);
    let d = d2.sqrt();
    if d >= radius {
        return 0.0;
    }
    let half = (radius * radius - d2).sqrt();
    let inside = ((t_mid + half).min(length) - (t_mid - half).max(0.0)).max(0.0);
    tau * (1.0 - d / radius) * inside
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sphere(center: Vec3, radius_m: f32, density_per_m: f32) -> Particle {
        Particle {
            position: center,
            velocity: Vec3::ZERO,
            age_s: 1.0,
            radius_m,
            density_per_m,
            albedo: Vec3::ONE,
        }
    }

    fn close(got: f32, want: f64) {
        assert!(
            (f64::from(got) - want).abs() < 1e-6,
            "T = {got}, closed form {want}"
        );
    }

    #[test]
    fn one_sphere_on_the_axis_before_inside_and_behind() {
        // Light at the origin, sphere of radius 1 and τ = 2 centred 5 m down -z: the axis ray
        // (d = 0) enters at 4 m and leaves at 6 m.
        let particles = [sphere(Vec3::new(0.0, 0.0, -5.0), 1.0, 2.0)];
        let t = |z: f32| transmittance(Vec3::ZERO, Vec3::new(0.0, 0.0, z), &particles);
        close(t(-3.0), 1.0);
        close(t(-4.5), (-2.0f64 * 0.5).exp());
        close(t(-5.0), (-2.0f64 * 1.0).exp());
        close(t(-8.0), (-2.0f64 * 2.0).exp());
    }

    #[test]
    fn an_oblique_ray_sees_the_density_of_its_distance_from_the_centre() {
        // The ray down -z passes the centre (3, 0, -4) at d = 3; with r = 4 the chord is
        // 2 sqrt(16 - 9) = 2 sqrt 7 long around t = 4, and the density τ(1 - 3/4) = τ/4.
        let particles = [sphere(Vec3::new(3.0, 0.0, -4.0), 4.0, 1.0)];
        let behind = transmittance(Vec3::ZERO, Vec3::new(0.0, 0.0, -10.0), &particles);
        close(behind, (-0.25 * 2.0 * 7f64.sqrt()).exp());
        // Halfway in: from 4 - sqrt 7 to 4.
        let mid = transmittance(Vec3::ZERO, Vec3::new(0.0, 0.0, -4.0), &particles);
        close(mid, (-0.25 * 7f64.sqrt()).exp());
        // A ray that misses the sphere sees nothing: the point (-5, 0, 0) lies on -x, 5 m
        // from a centre 5 m away from the light, at d = 5 > r.
        close(
            transmittance(Vec3::ZERO, Vec3::new(-5.0, 0.0, 0.0), &particles),
            1.0,
        );
    }

    #[test]
    fn overlapping_spheres_add_their_optical_depths() {
        // Two spheres on the axis overlapping between 5.5 and 6 m: centres 5 (r 1, τ 1) and
        // 6.5 (r 1, τ 3). The axis first, then an oblique ray by its own geometry.
        let particles = [
            sphere(Vec3::new(0.0, 0.0, -5.0), 1.0, 1.0),
            sphere(Vec3::new(0.0, 0.0, -6.5), 1.0, 3.0),
        ];
        let axis = |z: f32| transmittance(Vec3::ZERO, Vec3::new(0.0, 0.0, z), &particles);
        // At 5.75 m: 1.75 m of the first sphere, 0.25 m of the second.
        close(axis(-5.75), (-(1.75 + 3.0 * 0.25f64)).exp());
        // Behind both: 2 m of each.
        close(axis(-9.0), (-(2.0 + 3.0 * 2.0f64)).exp());
        // From (0, 1, 0) to (0, -1, -10), direction v = (0, -2, -10): the line runs through the
        // first centre (at its midpoint, y = 0, z = -5), so d1 = 0 and the chord is 2 m; the
        // second centre is |(0, -1, -6.5) x v| / |v| = 3 / sqrt(104) m off the line, and both
        // chords lie wholly between the light and p.
        let light = Vec3::new(0.0, 1.0, 0.0);
        let p = Vec3::new(0.0, -1.0, -10.0);
        let d2 = 3.0 / 104f64.sqrt();
        let tau1 = 1.0 * 2.0;
        let tau2 = 3.0 * (1.0 - d2) * 2.0 * (1.0 - d2 * d2).sqrt();
        close(transmittance(light, p, &particles), (-(tau1 + tau2)).exp());
    }

    #[test]
    fn occluders_block_what_they_hide_and_never_their_own_surface() {
        use crate::scene::BoxShape;
        let mut scene = Scene::thesis_plume();
        // A ground height that is no round number, as a bare file's is.
        scene.ground.height_m = -0.012_345;
        scene.ground.size_m = 20.0;
        scene.boxes = vec![BoxShape {
            center: Vec3::new(0.0, 0.5, 0.0),
            size: Vec3::ONE,
            albedo: Vec3::splat(0.5),
        }];
        let light = Vec3::new(0.0, 10.0, 0.0);
        let eps = 1e-3;
        let v = |p: Vec3| occluder_visibility(&scene, light, p, eps);
        // Points on the ground's plane, a float step above or below it, are lit.
        for dy in [0.0, 1e-7, -1e-7] {
            assert_eq!(
                v(Vec3::new(3.0, scene.ground.height_m + dy, 2.0)),
                Visibility::Lit
            );
        }
        // Straight under the box: blocked; on the box's lit top face: lit.
        assert_eq!(
            v(Vec3::new(0.1, scene.ground.height_m, 0.2)),
            Visibility::Blocked
        );
        assert_eq!(v(Vec3::new(0.1, 1.0, 0.2)), Visibility::Lit);
        // A point well below the ground, with the light above: the ground hides it.
        assert_eq!(v(Vec3::new(3.0, -1.0, 2.0)), Visibility::Blocked);
        // A ground point whose segment to the light grazes the box's edge x = 0.5 within the
        // epsilon: either answer is right, so neither is claimed.
        let h = scene.ground.height_m;
        // The segment from (x, h, 0) to the light crosses y = 1 at x (10 - 1) / (10 - h).
        let x_edge = 0.5 * (10.0 - h) / 9.0;
        assert_eq!(v(Vec3::new(x_edge, h, 0.0)), Visibility::KnifeEdge);
        assert_eq!(v(Vec3::new(x_edge + 0.01, h, 0.0)), Visibility::Lit);
        assert_eq!(v(Vec3::new(x_edge - 0.01, h, 0.0)), Visibility::Blocked);
    }
}
