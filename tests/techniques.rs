//! GPU tests of the shadow techniques against analytic transmittance and against `exact`
//! (issue: every thesis technique under one channel budget). They run on lavapipe and fail,
//! never skip, without an adapter.

mod common;

use common::{gpu, technique};
use glam::Vec3;
use smokeshadow::gpu::Gpu;
use smokeshadow::render::shaded::{rms_difference, shaded_points};
use smokeshadow::render::{
    OUTPUT_FORMAT, RenderOptions, Renderer, TechniqueConfig, render_offscreen,
};
use smokeshadow::scene::Scene;
use smokeshadow::shadow::{MemoryCase, SplatMode};
use smokeshadow::sim::{Particle, simulate};

const W: u32 = 256;
const H: u32 = 192;

fn reduced_plume() -> Scene {
    let mut scene = Scene::thesis_plume();
    scene.output.width_px = W;
    scene.output.height_px = H;
    scene
}

/// T at `points` for each configuration, in order (one renderer, switching techniques).
fn probe_all(
    gpu: &Gpu,
    scene: &Scene,
    particles: &[Particle],
    configs: &[TechniqueConfig],
    points: &[Vec3],
) -> Vec<Vec<f32>> {
    let mut renderer = Renderer::new(
        gpu,
        scene.output.width_px,
        scene.output.height_px,
        OUTPUT_FORMAT,
        &configs[0],
    )
    .unwrap();
    configs
        .iter()
        .map(|c| {
            renderer.set_technique(gpu, c).unwrap();
            renderer.probe(gpu, scene, particles, points).unwrap()
        })
        .collect()
}

/// One homogeneous particle of radius 1 m at the origin, extinction `TAU`, lit straight down
/// from 10 m by a narrow spotlight, and the analytic transmittance along light rays through it.
mod sphere {
    use super::*;

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
        let light = Vec3::new(0.0, LIGHT_HEIGHT, 0.0);
        let (mut points, mut expected) = (Vec::new(), Vec::new());
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
            }
        }
        (points, expected)
    }
}

#[test]
fn exact_matches_the_analytic_sphere_and_layered_techniques_converge_to_it() {
    let gpu = gpu();
    let scene = sphere::scene();
    let particles = [sphere::particle()];
    let (points, expected) = sphere::samples();
    let res = scene.shadow.resolution_px;

    // The reference at 2048² (1.6 mm texels at the sphere): the lookup blends the four light rays
    // around each point, and the density τ(1 − d/r) has a kink at d = 0 where that blend errs
    // at first order in the texel size: 1e-3 in T holds there from about 2 mm texels down.
    let exact = &probe_all(
        &gpu,
        &scene,
        &particles,
        &[technique("exact", 1, 2048, SplatMode::Segment)],
        &points,
    )[0];
    for (i, (t, e)) in exact.iter().zip(&expected).enumerate() {
        assert!(
            (t - e).abs() < 1e-3,
            "exact T at sample {i} ({}) is {t}, analytic {e}",
            points[i]
        );
    }
    // The CPU closed form has no texels: it meets the analytic curve to float precision
    // (the test's T is computed in f32, so 1e-5).
    let light = scene.light.position;
    for (i, (p, e)) in points.iter().zip(&expected).enumerate() {
        let t = smokeshadow::shadow::closed_form::transmittance(light, *p, &particles);
        assert!(
            (t - e).abs() < 1e-5,
            "closed-form T at sample {i} ({p}) is {t}, analytic {e}"
        );
    }

    // Every technique: finite T in [0, 1] at every budget, within a bound of the analytic curve
    // at 24 channels; the ones that converge get closer with every budget step.
    for entry in smokeshadow::shadow::contenders() {
        let name = entry.name;
        let configs: Vec<_> = [4, 8, 24]
            .iter()
            .map(|&b| technique(name, b.max(entry.min_channels), res, SplatMode::Segment))
            .collect();
        let results = probe_all(&gpu, &scene, &particles, &configs, &points);
        for t in &results {
            assert!(
                t.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v)),
                "{name}: T outside [0, 1]: {t:?}"
            );
        }
        let errors: Vec<f64> = results
            .iter()
            .map(|t| rms_difference(t, &expected))
            .collect();
        println!("{name}, segment splat: RMS T error at 4/8/24 channels: {errors:?}");
        // The depth-resolving techniques (those that converge with the budget, on the chord
        // splat `exact` uses) get closer at every step and end within 0.005 RMS at 24 channels
        // (measured: 0.0009-0.0015; the slicing of `has` has no depth inside one particle, and
        // `esm`/`bsm` keep a fixed number of values, so they are held only to T in [0, 1]).
        if entry.converges_with_budget && entry.uses_splat {
            assert!(
                errors[2] < errors[1] && errors[1] < errors[0],
                "{name}: error must shrink as the budget grows: {errors:?}"
            );
            assert!(
                errors[2] < 0.005,
                "{name}: RMS error {errors:?} at 24 channels"
            );
        }
    }
}

#[test]
fn error_against_exact_on_the_plume_shrinks_as_the_budget_grows() {
    let gpu = gpu();
    let scene = reduced_plume();
    let particles = simulate(&scene);
    let points = shaded_points(&scene, &particles, W, H, 4);
    let res = scene.shadow.resolution_px;
    let budgets = [6, 8, 16, 24];
    let exact = probe_all(
        &gpu,
        &scene,
        &particles,
        &[technique("exact", 1, res, SplatMode::Segment)],
        &points,
    )
    .remove(0);

    println!(
        "RMS transmittance error against exact over {} shaded points (thesis_plume, {res}² map)",
        points.len()
    );
    println!(
        "{:<10} {:<8} {:>9} {:>9} {:>9} {:>9}",
        "technique", "splat", 6, 8, 16, 24
    );
    for splat in [SplatMode::Segment, SplatMode::Point] {
        for entry in smokeshadow::shadow::contenders() {
            let name = entry.name;
            let configs: Vec<_> = budgets
                .iter()
                .map(|&b| technique(name, b, res, splat))
                .collect();
            let errors: Vec<f64> = probe_all(&gpu, &scene, &particles, &configs, &points)
                .iter()
                .map(|t| rms_difference(t, &exact))
                .collect();
            println!(
                "{name:<10} {:<8} {:>9.5} {:>9.5} {:>9.5} {:>9.5}",
                splat.name(),
                errors[0],
                errors[1],
                errors[2],
                errors[3]
            );
            // With segment splats (the density model `exact` uses) every converging technique
            // gets closer at each step; point splats converge to the point model instead.
            if splat == SplatMode::Segment && entry.converges_with_budget {
                assert!(
                    errors.windows(2).all(|w| w[1] < w[0]),
                    "{name} with segment splatting must converge 6 -> 8 -> 16 -> 24: {errors:?}"
                );
            }
        }
    }
}

#[test]
fn order_independent_maps_do_not_depend_on_the_particle_order() {
    // The renderer sorts the particles back to front for the camera before the build pass, so
    // moving the camera to the other side of the plume reverses the order in which the light
    // passes see them. The light space does not depend on the camera: T must not change.
    let gpu = gpu();
    let scene = reduced_plume();
    let mut behind = scene.clone();
    behind.camera.position = scene.camera.target * 2.0 - scene.camera.position;
    let particles = simulate(&scene);
    let points = shaded_points(&scene, &particles, W, H, 8);
    let res = scene.shadow.resolution_px;
    for entry in smokeshadow::shadow::REGISTRY
        .iter()
        .filter(|e| e.order_independent)
    {
        let name = entry.name;
        for splat in [SplatMode::Point, SplatMode::Segment] {
            let config = [technique(name, 16, res, splat)];
            let front = probe_all(&gpu, &scene, &particles, &config, &points).remove(0);
            let back = probe_all(&gpu, &behind, &particles, &config, &points).remove(0);
            let max_diff = front
                .iter()
                .zip(&back)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max);
            // Half-float maps add their terms in a different order: each sum rounds differently
            // by a few ulps of the running optical depth. Measured over emitter seeds 1-5 and
            // 2013 at 16 channels: osm and dom move T by at most 1.6e-3, bsm (whose maps hold
            // larger sums) by 2.2e-3 to 4.3e-3 depending on the seed (3.0e-3 on this scene's).
            assert!(
                max_diff < 5e-3,
                "{name} ({splat:?}): T changed by {max_diff} when the particle order reversed"
            );
        }
    }
}

#[test]
fn every_technique_at_every_thesis_budget_renders_a_finite_shadowed_plume() {
    let gpu = gpu();
    let scene = reduced_plume();
    let particles = simulate(&scene);
    let res = scene.shadow.resolution_px;
    let camera = smokeshadow::render::CameraMatrices::new(&scene, W, H);
    let ground = smokeshadow::render::shaded::lit_opaque_points(&scene, &camera, W, H, 2);
    let exact = probe_all(
        &gpu,
        &scene,
        &particles,
        &[technique("exact", 1, res, SplatMode::Segment)],
        &ground,
    )
    .remove(0);
    let in_shadow: Vec<usize> = (0..ground.len()).filter(|&i| exact[i] < 0.2).collect();
    let lit: Vec<usize> = (0..ground.len()).filter(|&i| exact[i] > 0.98).collect();
    assert!(
        in_shadow.len() > 50 && lit.len() > 50,
        "the plume should shadow part of the lit ground ({} shadowed, {} lit points)",
        in_shadow.len(),
        lit.len()
    );
    let mean = |t: &[f32], idx: &[usize]| idx.iter().map(|&i| t[i]).sum::<f32>() / idx.len() as f32;

    let shadowing = smokeshadow::shadow::REGISTRY
        .iter()
        .filter(|e| e.role != smokeshadow::shadow::Role::FrameBaseline);
    for entry in shadowing {
        let name = entry.name;
        for channels in [6, 8, 16, 24] {
            let config = technique(name, channels, res, SplatMode::Point);
            let frame =
                render_offscreen(&gpu, &scene, &particles, &config, &RenderOptions::default())
                    .unwrap();
            let pixels = (W * H) as usize;
            let mut smoke = 0;
            for y in 0..H {
                for x in 0..W {
                    let c = frame.hdr.get(x, y);
                    assert!(
                        c.iter().all(|v| v.is_finite() && *v >= 0.0),
                        "{name}/{channels}: pixel ({x}, {y}) = {c:?}"
                    );
                    smoke += usize::from(c[3] > 0.05);
                }
            }
            assert!(
                smoke > pixels / 20,
                "{name}/{channels}: only {smoke} of {pixels} pixels show smoke"
            );
            // The ground the exact reference puts in deep shadow is dark, and the ground it
            // leaves lit stays lit. Thresholds leave room for every technique's own error at 6
            // channels (FOM rings, HAS lacks depth), not for a missing or inverted shadow.
            let t = probe_all(&gpu, &scene, &particles, &[config], &ground).remove(0);
            let (dark, bright) = (mean(&t, &in_shadow), mean(&t, &lit));
            assert!(
                dark < 0.5 && bright > 0.9,
                "{name}/{channels}: mean T {dark} where exact < 0.2, {bright} where exact > 0.98"
            );
        }
    }
}

#[test]
fn reported_channels_and_bytes_match_each_techniques_formula() {
    let gpu = gpu();
    let mut scene = reduced_plume();
    scene.output.width_px = 96;
    scene.output.height_px = 64;
    let particles = simulate(&scene);
    let n = particles.len() as u64;
    let res = 128u32;
    let pixels = 96 * 64;
    let mut renderer = Renderer::new(
        &gpu,
        96,
        64,
        OUTPUT_FORMAT,
        &technique("none", 1, res, SplatMode::Point),
    )
    .unwrap();
    let target = smokeshadow::render::OffscreenTarget::new(&gpu, 96, 64);
    let budgets = [1u32, 2, 3, 4, 5, 6, 7, 8, 15, 16, 23, 24, 31, 32];
    for entry in smokeshadow::shadow::REGISTRY {
        for &b in budgets.iter().filter(|&&b| b >= entry.min_channels) {
            renderer
                .set_technique(&gpu, &technique(entry.name, b, res, SplatMode::Point))
                .unwrap();
            renderer
                .render(
                    &gpu,
                    &scene,
                    &particles,
                    &RenderOptions::default(),
                    &target.view,
                )
                .unwrap();
            let t = renderer.technique();
            let bytes = t.memory().total_bytes();
            // The formula each technique documents in its registry entry.
            let counters = t.counters();
            let expected = (entry.memory)(&MemoryCase {
                channels: b,
                resolution_px: res,
                particles: n,
                frame_pixels: pixels,
                counters: &counters,
            });
            if entry.name == smokeshadow::shadow::reference().name {
                // The lists hold every segment, with bounded headroom.
                let segments = counters.iter().find(|(k, _)| *k == "segments").unwrap().1;
                let capacity = counters
                    .iter()
                    .find(|(k, _)| *k == "segment_capacity")
                    .unwrap()
                    .1;
                assert!(segments > n, "exact stored only {segments} segments");
                assert!(capacity >= segments && capacity <= segments * 5 / 4 + 65536);
            }
            let (channels, expected) = (expected.channels, expected.bytes);
            assert_eq!(
                u64::from(t.channels_used()),
                channels,
                "{} at {b} channels",
                entry.name
            );
            assert_eq!(
                bytes,
                expected,
                "{} at {b} channels: ledger {:?}",
                entry.name,
                t.memory().entries()
            );
        }
    }
}

#[test]
fn budgets_below_a_techniques_minimum_name_it() {
    let gpu = gpu();
    let scene = reduced_plume();
    for entry in smokeshadow::shadow::REGISTRY
        .iter()
        .filter(|e| e.min_channels > 1)
    {
        let (name, min) = (entry.name, entry.min_channels);
        let err = Renderer::new(
            &gpu,
            W,
            H,
            OUTPUT_FORMAT,
            &technique(name, min - 1, scene.shadow.resolution_px, SplatMode::Point),
        )
        .err()
        .unwrap()
        .to_string();
        assert!(
            err.contains(&format!("allowed {min}..=32")),
            "{name}: {err}"
        );
    }
    let err = Renderer::new(
        &gpu,
        W,
        H,
        OUTPUT_FORMAT,
        &technique("osm", 33, scene.shadow.resolution_px, SplatMode::Point),
    )
    .err()
    .unwrap()
    .to_string();
    assert!(err.contains("1..=32"), "{err}");
}
