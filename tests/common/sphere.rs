//! One homogeneous particle of radius 1 m at the origin, extinction `TAU`, lit straight down
//! from 10 m by a narrow spotlight, and the analytic transmittance along light rays through it.

use glam::Vec3;
use smokeshadow::scene::Scene;
use smokeshadow::sim::Particle;

pub const TAU: f32 = 1.5;
pub const RADIUS: f32 = 1.0;
pub const LIGHT_HEIGHT: f32 = 10.0;
/// Impact parameters of the probed rays, metres.
pub const IMPACT: [f32; 4] = [0.0, 0.3, 0.6, 0.85];

pub fn scene() -> Scene {
    let mut scene = Scene::thesis_plume();
    scene.output.width_px = 64;
    scene.output.height_px = 48;
    scene.light.position = Vec3::new(0.0, LIGHT_HEIGHT, 0.0);
    scene.light.target = Vec3::ZERO;
    scene.light.cone_angle_deg = 10.0;
    scene.boxes.clear();
    scene.shadow.resolution_px = 512;
    scene
}

pub fn particle() -> Particle {
    Particle {
        position: Vec3::ZERO,
        velocity: Vec3::ZERO,
        age_s: 1.0,
        radius_m: RADIUS,
        density_per_m: TAU,
        albedo: Vec3::ONE,
    }
}

/// Points along each probed ray, from just before the chord to just after it, with the
/// analytic T(z) = exp(−τ(1 − d/r)(z − z_entry)) (1 before, constant after).
pub fn samples() -> (Vec<Vec3>, Vec<f32>) {
    let (points, expected, _) = samples_and_chords();
    (points, expected)
}

/// [`samples`], and with them T's chord: T linear from 1 at the entry to the analytic T at
/// the exit (what a segment with linear T inside it, `avsm`'s, holds).
pub fn samples_and_chords() -> (Vec<Vec3>, Vec<f32>, Vec<f32>) {
    let light = Vec3::new(0.0, LIGHT_HEIGHT, 0.0);
    let (mut points, mut expected, mut chords) = (Vec::new(), Vec::new(), Vec::new());
    for d in IMPACT {
        // A ray from the light at angle θ to the axis passes the centre at distance
        // 10·sin θ; its chord is centred at t = 10·cos θ with half-length sqrt(r² − d²).
        let sin = d / LIGHT_HEIGHT;
        let cos = (1.0 - sin * sin).sqrt();
        let dir = Vec3::new(sin, -cos, 0.0);
        let (t_mid, w) = (LIGHT_HEIGHT * cos, (RADIUS * RADIUS - d * d).sqrt());
        let sigma = TAU * (1.0 - d / RADIUS);
        for i in 0..=40 {
            let t = t_mid - 1.2 * w + 2.4 * w * i as f32 / 40.0;
            points.push(light + dir * t);
            let inside = (t - (t_mid - w)).clamp(0.0, 2.0 * w);
            expected.push((-sigma * inside).exp());
            let exit = (-sigma * 2.0 * w).exp();
            chords.push(1.0 - (1.0 - exit) * inside / (2.0 * w));
        }
    }
    (points, expected, chords)
}
