//! A scene's density volume (`[volume]`) in the frame: parsed and checked like every scene
//! field, marched by the eye against the closed form of a homogeneous box, shadowed by `exact`
//! to the box's closed form, and refused in one line by a technique that cannot shadow it.

use smokeshadow::Wait;
mod common;

use glam::Vec3;
use smokeshadow::render::{OUTPUT_FORMAT, OffscreenTarget, RenderOptions, Renderer};
use smokeshadow::scene::{Scene, VolumeSpec};
use smokeshadow::shadow::SplatMode;

/// Extinction of the test box, 1/m, and its sides, metres.
const SIGMA: f32 = 0.8;
const BOX: Vec3 = Vec3::new(2.0, 1.5, 1.0);
const BOX_CENTER: Vec3 = Vec3::new(0.0, 2.0, 0.0);

/// A homogeneous box straight under a spotlight and straight in front of the camera: the light
/// ray to a point under the box's centre and the eye ray through the middle pixel run through
/// the box's interior; every pass samples the box itself (its closed form in the grid's index
/// space), and `exact` takes its chord in closed form.
fn box_scene() -> Scene {
    let mut scene = Scene::thesis_plume();
    scene.emitters.clear();
    scene.boxes.clear();
    scene.output.width_px = 33;
    scene.output.height_px = 33;
    scene.camera.position = Vec3::new(0.0, 2.0, 8.0);
    scene.camera.target = BOX_CENTER;
    scene.light.position = Vec3::new(0.0, 9.0, 0.0);
    scene.light.target = Vec3::ZERO;
    scene.volume = Some(VolumeSpec {
        shape: "box".to_owned(),
        center_m: BOX_CENTER,
        size_m: BOX,
        density_scale_per_m: SIGMA,
        voxels: 16,
        jitter: 0.0,
        eye_steps: 256,
        ..VolumeSpec::default()
    });
    scene.validate().unwrap();
    scene
}

#[test]
fn a_volume_table_parses_and_its_bad_fields_are_named() {
    let base = "name = \"v\"\n[volume]\n";
    let scene = Scene::from_toml_str(
        &format!("{base}shape = \"sphere\"\nradius_m = 2.0\ndensity_scale_per_m = 0.5\n"),
        "t",
    )
    .unwrap();
    // A volume scene holds no particles unless it names them.
    assert!(scene.emitters.is_empty() && scene.particles.is_none());
    let volume = scene.volume.as_ref().unwrap();
    assert_eq!((volume.radius_m, volume.grid.as_str()), (2.0, "density"));
    // It writes back to the same scene.
    assert_eq!(Scene::from_toml_str(&scene.to_toml(), "t").unwrap(), scene);

    for (body, expected) in [
        ("", "names no source"),
        (
            "shape = \"box\"\nprocedural = \"cloud\"\n",
            "more than one source",
        ),
        ("shape = \"cone\"\n", "volume.shape = \"cone\""),
        ("procedural = \"fog\"\n", "volume.procedural = \"fog\""),
        ("shape = \"box\"\neye_steps = 0\n", "volume.eye_steps = 0"),
        ("shape = \"box\"\njitter = 2.0\n", "volume.jitter = 2"),
        (
            "shape = \"box\"\ndensity_scale_per_m = -1.0\n",
            "volume.density_scale_per_m = -1",
        ),
        (
            "procedural = \"cloud\"\n[volume.cloud]\ncoverage = 1.5\n",
            "volume.cloud.coverage = 1.5",
        ),
        (
            "procedural = \"cloud\"\n[volume.cloud]\nwind_m_per_s = [5.0, 2000.0]\n",
            "volume.cloud.wind_m_per_s[1] = 2000 is out of range",
        ),
        ("shape = \"box\"\ncolour = 1\n", "unknown field `colour`"),
    ] {
        let err = Scene::from_toml_str(&format!("{base}{body}"), "t")
            .unwrap_err()
            .to_string();
        assert!(err.contains(expected), "{body:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{err}");
    }
}

#[test]
fn the_eye_sees_the_box_with_its_closed_form_transmittance_and_exact_shadows_to_it() {
    let gpu = common::gpu();
    let scene = box_scene();
    let config = common::technique("exact", 1, 256, SplatMode::Segment);
    let (w, h) = (scene.output.width_px, scene.output.height_px);
    let mut renderer = Renderer::new(&gpu, w, h, OUTPUT_FORMAT, &config)
        .wait()
        .unwrap();
    let target = OffscreenTarget::new(&gpu, w, h);
    renderer
        .render(&gpu, &scene, &[], &RenderOptions::default(), &target.view)
        .wait()
        .unwrap();
    let hdr = smokeshadow::gpu::read_texture_rgba16f(&gpu, renderer.hdr_texture())
        .wait()
        .unwrap();
    // The middle pixel's ray runs along -z through the box's depth: alpha = 1 - exp(-σ d).
    let alpha = hdr.get(w / 2, h / 2)[3];
    let expected = 1.0 - (-SIGMA * BOX.z).exp();
    assert!(
        (alpha - expected).abs() < 2e-3,
        "alpha {alpha}, closed form {expected}"
    );
    // A corner pixel sees past the box: no smoke.
    assert_eq!(hdr.get(0, 0)[3], 0.0);

    // exact's light under the box's centre crossed its height: T = exp(-σ h); beside the box,
    // nothing.
    let points = [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.1),
        Vec3::new(3.0, 0.0, 0.0),
    ];
    let t = renderer.probe(&gpu, &scene, &[], &points).wait().unwrap();
    let closed = (-SIGMA * BOX.y).exp();
    for (p, t) in points.iter().zip(&t).take(2) {
        assert!(
            (t - closed).abs() < 1e-4,
            "T at {p} = {t}, closed form {closed}"
        );
    }
    assert_eq!(t[2], 1.0);
}

#[test]
fn a_technique_that_cannot_shadow_a_volume_is_refused_in_one_line() {
    let gpu = common::gpu();
    let scene = box_scene();
    let (w, h) = (scene.output.width_px, scene.output.height_px);
    for entry in smokeshadow::shadow::REGISTRY {
        let smokeshadow::shadow::VolumeSupport::Refuses(why) = entry.volume else {
            continue;
        };
        let config = common::technique(
            entry.name,
            entry.min_channels.max(8),
            64,
            SplatMode::Segment,
        );
        let mut renderer = Renderer::new(&gpu, w, h, OUTPUT_FORMAT, &config)
            .wait()
            .unwrap();
        let target = OffscreenTarget::new(&gpu, w, h);
        let err = renderer
            .render(&gpu, &scene, &[], &RenderOptions::default(), &target.view)
            .wait()
            .unwrap_err()
            .to_string();
        assert!(
            err.contains(entry.name) && err.contains(why) && err.lines().count() == 1,
            "{err}"
        );
    }
}

#[test]
fn a_bare_vdb_file_renders_as_a_framed_scene() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/volumes/openusd_smoke_000003.vdb");
    let scene = smokeshadow::particles::open_scene(Some(&path)).unwrap();
    let volume = scene.volume.as_ref().unwrap();
    assert!(volume.density_scale_per_m > 0.0 && scene.emitters.is_empty());
    // The empty file's grid has nothing to frame: one line.
    let empty = path.with_file_name("openusd_smoke_000001_empty.vdb");
    let err = smokeshadow::particles::open_scene(Some(&empty))
        .unwrap_err()
        .to_string();
    assert!(err.contains("no active voxels"), "{err}");
}

/// T at `points` of the box scene for `name` at `channels` (its minimum, if more).
fn box_probe(gpu: &smokeshadow::gpu::Gpu, name: &str, channels: u32, points: &[Vec3]) -> Vec<f32> {
    let scene = box_scene();
    let entry = smokeshadow::shadow::find(name).unwrap();
    let config = common::technique(
        name,
        channels.max(entry.min_channels),
        128,
        SplatMode::Segment,
    );
    common::probe_all(gpu, &scene, &[], &[config], points).remove(0)
}

/// Points on the vertical line through the box's centre, from above its top to the ground.
fn vertical_line() -> Vec<Vec3> {
    let top = BOX_CENTER.y + 0.5 * BOX.y;
    (0..=8)
        .map(|i| {
            Vec3::new(
                0.05,
                top + 0.2 - f32::from(i as u8) * (top + 0.2) / 8.0,
                0.05,
            )
        })
        .collect()
}

#[test]
fn every_technique_that_shadows_a_volume_darkens_beneath_it_and_not_beside_it() {
    let gpu = common::gpu();
    let mut points = vertical_line();
    points.push(Vec3::new(3.0, 0.0, 0.0));
    for entry in smokeshadow::shadow::REGISTRY {
        if entry.volume != smokeshadow::shadow::VolumeSupport::Shadows || entry.name == "none" {
            continue;
        }
        let t = box_probe(&gpu, entry.name, 24, &points);
        let (line, beside) = t.split_at(points.len() - 1);
        assert!(
            (beside[0] - 1.0).abs() < 1e-3,
            "{}: T beside {}",
            entry.name,
            beside[0]
        );
        assert!(
            line[0] > 0.99,
            "{}: T above the box {}",
            entry.name,
            line[0]
        );
        assert!(
            *line.last().unwrap() < 0.5,
            "{}: T on the ground under the box {:?}",
            entry.name,
            line
        );
        // Down through the box, the light only falls, up to what a march towards the light
        // may misplace: the box is hard-edged, so a midpoint march of N steps over its
        // support (the box and two voxels on either side, here 2 m) counts up to one step's
        // optical depth σ·Δ more or less as the point moves. 16 steps (`srm`'s default) is the
        // fewest any technique takes; the maps' builds take 64.
        let voxel = BOX.x / 16.0;
        let step = (BOX.y + 4.0 * voxel) / 16.0;
        let rise = (SIGMA * step).exp();
        for w in line.windows(2) {
            assert!(
                w[1] <= w[0] * rise + 2e-3,
                "{}: T rises downwards by more than one step of the march: {line:?}",
                entry.name
            );
        }
    }
}

#[test]
fn the_maps_that_converge_hold_the_volumes_whole_optical_depth_and_shrink_their_error() {
    let gpu = common::gpu();
    let line = vertical_line();
    let exact = box_probe(&gpu, "exact", 1, &line);
    let closed = (-SIGMA * BOX.y).exp();
    assert!((exact.last().unwrap() - closed).abs() < 1e-4);
    for entry in smokeshadow::shadow::REGISTRY {
        if entry.volume != smokeshadow::shadow::VolumeSupport::Shadows
            || !entry.converges_with_budget
        {
            continue;
        }
        let rms = |channels: u32| {
            let t = box_probe(&gpu, entry.name, channels, &line);
            // Beneath the whole box every slice, layer and harmonic has all of it.
            let ground = *t.last().unwrap();
            // The volume point-samples the density at its voxels' centres (no technique
            // prefilters), so a face of the box between two centres moves by up to half a
            // voxel, each side: at 4 channels, a 1.8% thicker box (measured 6.4e-3 off); the
            // maps march the density grid along each texel's ray.
            let bound = match entry.name {
                "volume" => 1e-2,
                _ => 5e-3,
            };
            assert!(
                (ground - closed).abs() < bound,
                "{} at {channels}: T on the ground {ground}, closed form {closed}",
                entry.name
            );
            let sum: f32 = t.iter().zip(&exact).map(|(a, b)| (a - b).powi(2)).sum();
            (sum / t.len() as f32).sqrt()
        };
        // A homogeneous box's optical depth along a light ray is piecewise linear with two
        // kinks, which the deep maps hold exactly from their smallest budget: there the error
        // is the build's sampling, and more channels must not make it worse.
        let (coarse, fine) = (rms(4), rms(24));
        assert!(
            fine < coarse || (fine <= coarse + 1e-6 && fine < 5e-3),
            "{}: RMS ΔT {fine} at 24 channels, {coarse} at 4",
            entry.name
        );
    }
}

#[test]
fn exact_shadows_a_sphere_by_its_chord_in_closed_form_off_every_axis() {
    // A homogeneous ball under a point-like spotlight, probed at points whose light rays cut
    // it off every axis of its grid (whose cells are not cubes: an ellipsoid in index space):
    // T = exp(-σ·chord), the chord from the ray-sphere quadratic written here.
    const CENTER: Vec3 = Vec3::new(0.3, 2.1, -0.2);
    const RADIUS: f32 = 0.9;
    let mut scene = box_scene();
    scene.volume = Some(VolumeSpec {
        shape: "sphere".to_owned(),
        center_m: CENTER,
        radius_m: RADIUS,
        density_scale_per_m: SIGMA,
        voxels: 12,
        ..VolumeSpec::default()
    });
    scene.validate().unwrap();
    let light = scene.light.position.as_dvec3();
    let closed_form = |p: glam::DVec3| -> f64 {
        let d = p - light;
        let oc = light - CENTER.as_dvec3();
        let (a, b) = (d.length_squared(), oc.dot(d));
        let c = oc.length_squared() - f64::from(RADIUS).powi(2);
        let disc = b * b - a * c;
        if disc <= 0.0 {
            return 1.0;
        }
        let (t0, t1) = ((-b - disc.sqrt()) / a, (-b + disc.sqrt()) / a);
        let inside = (t1.min(1.0) - t0.max(0.0)).max(0.0);
        (-f64::from(SIGMA) * inside * d.length()).exp()
    };
    let points: Vec<Vec3> = (0..24)
        .map(|i| {
            let a = i as f32 * 0.61;
            Vec3::new(
                0.25 + 0.8 * a.cos(),
                0.1 + 0.11 * i as f32,
                -0.1 + 0.7 * a.sin(),
            )
        })
        .collect();
    let gpu = common::gpu();
    let config = common::technique("exact", 1, 128, SplatMode::Segment);
    let t = common::probe_all(&gpu, &scene, &[], &[config], &points).remove(0);
    let mut shadowed = 0;
    for (p, t) in points.iter().zip(&t) {
        let expected = closed_form(p.as_dvec3());
        shadowed += usize::from(expected < 0.9);
        assert!(
            (f64::from(*t) - expected).abs() < 2e-5,
            "at {p}: exact {t}, closed form {expected}"
        );
    }
    assert!(
        shadowed >= 8,
        "only {shadowed} of the points are in the ball's shadow"
    );
}
