//! GPU tests of the slice-based techniques' options from the thesis' future work (chapter 5):
//! the monotone cubic between boundaries (`osm_interp`, `dom_interp` = cubic) and DOM's start
//! depth from enlarged spheres (`dom_start_dilation`). They run on lavapipe and fail, never
//! skip, without an adapter.

use smokeshadow::Wait;
mod common;

use common::{REDUCED_H as H, REDUCED_W as W, gpu, probe_all, reduced_plume, sphere, technique};
use glam::Vec3;
use smokeshadow::gpu::Gpu;
use smokeshadow::render::shaded::{rms_difference, shaded_points};
use smokeshadow::render::{OUTPUT_FORMAT, Renderer, TechniqueConfig};
use smokeshadow::scene::Scene;
use smokeshadow::shadow::{LightSpace, SplatMode, parse_param, set_param, slice_interp};
use smokeshadow::sim::{Particle, simulate};

/// `name` at `channels` with `params` (`KEY=VALUE`, as the CLI spells them).
fn config(name: &str, channels: u32, splat: SplatMode, params: &[&str]) -> TechniqueConfig {
    let mut config = technique(name, channels, 512, splat);
    for p in params {
        let (key, value) = parse_param(p).unwrap();
        set_param(&mut config.params, &key, &value).unwrap();
    }
    config
}

/// Light rays through the plume (towards every 400th particle), each as the unit direction from
/// the light; and the frame's light space.
fn plume_rays(scene: &Scene, particles: &[Particle]) -> (Vec<Vec3>, LightSpace) {
    let light = LightSpace::cone(&scene.light, particles);
    let dirs = particles
        .iter()
        .step_by(250)
        .map(|p| (p.position - scene.light.position).normalize())
        .collect();
    (dirs, light)
}

/// The point at normalised light depth `depth01` (0 at the smoke's near bound, 1 at its far
/// bound) along the light ray `dir`.
fn at_depth(light: &LightSpace, dir: Vec3, depth01: f64) -> Vec3 {
    let (near, far) = (f64::from(light.near_m), f64::from(light.far_m));
    let t = near + (far - near) * depth01;
    (light.position.as_dvec3() + dir.as_dvec3() * t).as_vec3()
}

#[test]
fn cubic_transmittance_never_rises_along_light_rays_through_the_plume() {
    // Along a light ray the lookup reads every boundary at the same map position, and each
    // texel's boundaries hold non-decreasing Ω (sums of non-negative terms, rounded in the same
    // order): the monotone cubic through them never decreases, so T never rises. 1e-5 is f32
    // rounding (measured: 1.2e-6, ten ulps near T = 1, with the map fitted to the smoke; 5e-9
    // under the cone's framing); a cubic that overshot would rise by a good part of a slice's
    // ΔT (1e-2 and more).
    let gpu = gpu();
    let scene = reduced_plume();
    let particles = simulate(&scene);
    let (dirs, light) = plume_rays(&scene, &particles);
    const SAMPLES: usize = 240;
    let points: Vec<Vec3> = dirs
        .iter()
        .flat_map(|&dir| {
            (0..SAMPLES)
                .map(move |i| at_depth(&light, dir, -0.05 + 1.1 * i as f64 / (SAMPLES - 1) as f64))
        })
        .collect();
    for splat in [SplatMode::Point, SplatMode::Segment] {
        for (name, extra) in [
            ("osm", None),
            ("dom", None),
            ("dom", Some("dom_layer_growth=16")),
            ("dom", Some("dom_start_dilation=2")),
        ] {
            for channels in [6, 24] {
                let with = |interp: &str| {
                    let key = format!("{name}_interp={interp}");
                    let mut params = vec![key.as_str()];
                    params.extend(extra);
                    config(name, channels, splat, &params)
                };
                let results = probe_all(
                    &gpu,
                    &scene,
                    &particles,
                    &[with("linear"), with("cubic")],
                    &points,
                );
                let (linear, cubic) = (&results[0], &results[1]);
                let what = format!("{name}/{channels} {extra:?} {splat:?}");
                assert!(
                    cubic
                        .iter()
                        .all(|t| t.is_finite() && (0.0..=1.0).contains(t)),
                    "{what}: T outside [0, 1]"
                );
                let mut worst_rise = 0.0f32;
                for ray in cubic.chunks(SAMPLES) {
                    for w in ray.windows(2) {
                        worst_rise = worst_rise.max(w[1] - w[0]);
                    }
                }
                let moved = linear
                    .iter()
                    .zip(cubic)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0f32, f32::max);
                println!("{what}: cubic moves T by up to {moved}, rises by {worst_rise}");
                assert!(worst_rise <= 1e-5, "{what}: T rises by {worst_rise}");
                // The option is wired: it changes T between boundaries (measured by up to
                // 0.10-0.71).
                assert!(moved > 1e-3, "{what}: cubic equals linear ({moved})");
                // The shadow stays where the smoke is: the rays end in it.
                let last = cubic.chunks(SAMPLES).map(|ray| ray[SAMPLES - 1]);
                assert!(last.fold(1.0f32, f32::min) < 0.5, "{what}");
            }
        }
    }
}

#[test]
fn gpu_cubic_is_the_cpu_mirror_through_the_boundaries_the_linear_lookup_reads() {
    // At a boundary depth (s = k) the linear lookup returns that boundary's Ω exactly, so
    // -ln T there gives the knots; the cubic between them must be the CPU mirror's monotone
    // cubic through those knots. The tolerance is f32: ln/exp round-trips and the depth of a
    // point computed on the CPU in f64 and on the GPU in f32 (s off by ~1e-5).
    let gpu = gpu();
    let scene = reduced_plume();
    let particles = simulate(&scene);
    let (dirs, light) = plume_rays(&scene, &particles);
    for channels in [4u32, 8] {
        let b = f64::from(channels);
        let knots: Vec<f64> = (0..=channels).map(f64::from).collect();
        let between: Vec<f64> = (0..channels * 8)
            .map(|i| (f64::from(i) + 0.5) / 8.0)
            .collect();
        let points = |at: &[f64]| -> Vec<Vec3> {
            dirs.iter()
                .flat_map(|&dir| at.iter().map(move |&s| at_depth(&light, dir, s / b)))
                .collect()
        };
        let linear_cfg = config("osm", channels, SplatMode::Point, &["osm_interp=linear"]);
        let cubic_cfg = config("osm", channels, SplatMode::Point, &["osm_interp=cubic"]);
        let at_knots =
            probe_all(&gpu, &scene, &particles, &[linear_cfg], &points(&knots)).remove(0);
        let cubic = probe_all(&gpu, &scene, &particles, &[cubic_cfg], &points(&between)).remove(0);
        let (mut worst, mut compared) = (0.0f32, 0);
        for (ray, (t_knots, t_cubic)) in at_knots
            .chunks(knots.len())
            .zip(cubic.chunks(between.len()))
            .enumerate()
        {
            // Behind enough smoke T underflows (Ω > ~100 with point splats through the core):
            // only intervals whose four knots are all recoverable are compared.
            let omega: Vec<f32> = t_knots.iter().map(|t| -t.ln()).collect();
            for (s, t) in between.iter().zip(t_cubic) {
                let k = *s as usize;
                let n = channels as usize;
                let around = [k.max(1) - 1, k, k + 1, (k + 2).min(n)];
                if around.iter().any(|&i| omega[i] > 30.0) {
                    continue;
                }
                let omega = slice_interp::interval(
                    around.map(|i| i as f32),
                    around.map(|i| omega[i]),
                    k == 0,
                    k + 1 == n,
                    *s as f32,
                );
                worst = worst.max(((-omega).exp() - t).abs());
                compared += 1;
            }
            assert!(t_knots[0] > 0.99, "ray {ray} starts in front of the smoke");
        }
        assert!(
            compared > between.len() * dirs.len() / 3,
            "compared {compared}"
        );
        println!(
            "osm/{channels}: GPU cubic against the CPU mirror at {compared} points: max |ΔT| \
             {worst}"
        );
        assert!(
            worst < 2e-4,
            "osm/{channels}: off the CPU mirror by {worst}"
        );
    }
}

/// Points on the axis through the analytic sphere's chord (tests/common/sphere.rs; y from 0.9
/// down to -0.9, off the ends where the four rays around a point enter at slightly different
/// depths), and the analytic T: along the axis its optical depth rises linearly.
fn sphere_axis() -> (Vec<Vec3>, Vec<f32>) {
    (0..=72)
        .map(|i| {
            let y = 0.9 - 1.8 * i as f32 / 72.0;
            (Vec3::new(0.0, y, 0.0), (-sphere::TAU * (1.0 - y)).exp())
        })
        .unzip()
}

#[test]
fn cubic_is_linear_where_optical_depth_is_linear_in_depth() {
    // Through one homogeneous sphere (segment splats) Ω rises linearly with depth along each
    // ray, so on the axis the boundaries' Ω (a bilinear blend of four rays' linear Ω) are
    // collinear and the cubic is the linear lookup, up to the half-float rounding of the stored
    // Ω (2^-11 relative, ~1.5e-3 at Ω = 3, which bends the tangents slightly: measured up to
    // 2.6e-5 in T; 1e-3 bounds what the rounding could do).
    // On `dom`'s geometric layers (`dom_layer_growth` = 16: at 6 channels each of the 5 layers
    // twice the one before) the linear lookup interpolates in the
    // layer coordinate, which is not linear in depth, while the cubic interpolates in depth on
    // the layers' own knots: there it is far closer to the analytic T (measured RMS 0.0128 ->
    // 0.0013 at 6 channels, 0.0053 -> 0.0013 at 8; the rest is the 512² map's, as linear's on
    // uniform layers).
    let gpu = gpu();
    let scene = sphere::scene();
    let particles = [sphere::particle()];
    let (points, analytic) = sphere_axis();
    for (name, channels) in [("osm", 24), ("osm", 8), ("dom", 24), ("dom", 6)] {
        // `dom` on uniform layers from the sphere itself (the tuned defaults space them
        // geometrically: that case is below).
        let with = |interp: &str| {
            config(
                name,
                channels,
                SplatMode::Segment,
                &[
                    &format!("{name}_interp={interp}"),
                    "dom_layer_growth=1",
                    "dom_start_dilation=1",
                ],
            )
        };
        let results = probe_all(
            &gpu,
            &scene,
            &particles,
            &[with("linear"), with("cubic")],
            &points,
        );
        let off = results[0]
            .iter()
            .zip(&results[1])
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        println!(
            "{name}/{channels}: cubic against linear on the axis: max |ΔT| {off}; RMS against \
             analytic: linear {:.5}, cubic {:.5}",
            rms_difference(&results[0], &analytic),
            rms_difference(&results[1], &analytic)
        );
        assert!(off < 1e-3, "{name}/{channels}: cubic off linear by {off}");
    }
    for channels in [6, 8] {
        let with = |interp: &str| {
            config(
                "dom",
                channels,
                SplatMode::Segment,
                &[&format!("dom_interp={interp}"), "dom_layer_growth=16"],
            )
        };
        let results = probe_all(
            &gpu,
            &scene,
            &particles,
            &[with("linear"), with("cubic")],
            &points,
        );
        let (linear, cubic) = (
            rms_difference(&results[0], &analytic),
            rms_difference(&results[1], &analytic),
        );
        println!("dom/{channels}, growth 16: RMS against analytic: linear {linear}, cubic {cubic}");
        assert!(
            cubic < 0.5 * linear,
            "dom/{channels}, growth 16: cubic {cubic} against linear {linear}"
        );
    }
}

#[test]
fn dom_proxy_start_is_never_behind_the_sharp_start() {
    // Every enlarged sphere contains its particle's sphere, so along every texel's ray it is
    // entered at or before the particle's; the MIN over more and earlier entries is at or before
    // the sharp start everywhere (where no particle is hit the sharp start stays at the cleared
    // 1.0). Half-float rounding is monotone, so the comparison survives storage exactly; 1e-6
    // covers the two passes' billboards interpolating a texel's ray direction differently.
    let gpu = gpu();
    let scene = reduced_plume();
    let particles = simulate(&scene);
    let points = shaded_points(&scene, &particles, (W, H), 4, None);
    let starts: Vec<Vec<f32>> = ["1", "1.5", "2"]
        .iter()
        .map(|d| {
            let mut renderer = Renderer::new(
                &gpu,
                W,
                H,
                OUTPUT_FORMAT,
                &config(
                    "dom",
                    8,
                    SplatMode::Point,
                    &[&format!("dom_start_dilation={d}")],
                ),
            )
            .wait()
            .unwrap();
            let t = renderer
                .probe(&gpu, &scene, &particles, &points)
                .wait()
                .unwrap();
            assert!(
                t.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v)),
                "dilation {d}: T outside [0, 1]"
            );
            let maps = renderer.technique().debug_maps();
            assert!(
                maps[0].channels[0].contains("starts"),
                "{}",
                maps[0].channels[0]
            );
            smokeshadow::gpu::read_texture_r16f(&gpu, maps[0].view.texture())
                .wait()
                .unwrap()
        })
        .collect();
    let sharp = &starts[0];
    let smoke = sharp.iter().filter(|&&z| z < 1.0).count();
    assert!(smoke > sharp.len() / 20, "{smoke} texels see smoke");
    for (d, proxy) in ["1.5", "2"].iter().zip(&starts[1..]) {
        let behind = sharp
            .iter()
            .zip(proxy)
            .map(|(s, p)| p - s)
            .fold(f32::MIN, f32::max);
        let earlier: Vec<f32> = sharp
            .iter()
            .zip(proxy)
            .filter(|(s, _)| **s < 1.0)
            .map(|(s, p)| s - p)
            .collect();
        let mean = earlier.iter().sum::<f32>() / earlier.len() as f32;
        println!(
            "dilation {d}: proxy behind sharp by at most {behind}, ahead by {mean} on average"
        );
        assert!(
            behind <= 1e-6,
            "dilation {d}: the proxy starts {behind} behind"
        );
        assert!(mean > 0.0, "dilation {d}: the proxy starts no earlier");
    }
}

/// RMS T error against `exact` over the shaded points of the reduced thesis scene `scene_name`
/// (the sweep's metric at a quarter of its resolution), for each configuration.
fn errors_against_exact(gpu: &Gpu, scene_name: &str, configs: &[TechniqueConfig]) -> Vec<f64> {
    let mut scene = Scene::embedded(scene_name).unwrap();
    scene.output.width_px = W;
    scene.output.height_px = H;
    let particles = simulate(&scene);
    let points = shaded_points(&scene, &particles, (W, H), 4, None);
    let mut all = vec![technique("exact", 1, 512, SplatMode::Segment)];
    all.extend_from_slice(configs);
    let t = probe_all(gpu, &scene, &particles, &all, &points);
    t[1..].iter().map(|c| rms_difference(c, &t[0])).collect()
}

#[test]
fn cubic_against_exact_helps_segment_splats() {
    // Measured here (RMS T against exact, linear -> cubic, 24/16 channels):
    //   segment splats: osm 0.0117 -> 0.0049, 0.0204 -> 0.0089; dom 0.0072 -> 0.0030,
    //   0.0145 -> 0.0059 (thesis_plume); osm 0.0187 -> 0.0078, 0.0323 -> 0.0159; dom
    //   0.0139 -> 0.0055, 0.0300 -> 0.0171 (thesis_wind): 0.40-0.57 of linear's error;
    //   point splats: 1.18-1.36 times linear's (osm 0.0831 -> 0.1010 at 24 on the plume).
    // Segment splats put Ω on the chords, smooth in depth between boundaries, which the cubic
    // follows better than the chords' secants; a point splat makes Ω a staircase whose steps
    // linear interpolation smears over a slice (as the chord density of `exact` does) and the
    // cubic sharpens back into steps. At 8 and 6 channels the sign depends on the scene and
    // technique. Only the segment splats' gain is held (cubic under 0.7 of linear's error):
    // it is what the cubic is for, on the default model. That the cubic does worse with point
    // splats is a finding about the thesis' model, stated in the README's table (measured with
    // `sweep --splat point,segment`), not a property held here: a better point-splat lookup
    // must not fail a test.
    let gpu = gpu();
    let splat = SplatMode::Segment;
    for scene in ["thesis_plume", "thesis_wind"] {
        for name in ["osm", "dom"] {
            let configs: Vec<TechniqueConfig> = [24, 16]
                .iter()
                .flat_map(|&b| {
                    ["linear", "cubic"]
                        .map(|i| config(name, b, splat, &[&format!("{name}_interp={i}")]))
                })
                .collect();
            let e = errors_against_exact(&gpu, scene, &configs);
            for (budget, pair) in [24, 16].iter().zip(e.chunks(2)) {
                let (linear, cubic) = (pair[0], pair[1]);
                let what = format!("{scene} {name}/{budget}: {linear} -> {cubic}");
                assert!(cubic < 0.7 * linear, "{what}");
            }
        }
    }
}
