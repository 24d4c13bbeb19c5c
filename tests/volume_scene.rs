//! A scene's density volume (`[volume]`) in the frame: parsed and checked like every scene
//! field, marched by the eye against the closed form of a homogeneous box, shadowed by `exact`
//! to the box's closed form, and refused in one line by a technique that cannot shadow it.

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
/// ray to a point under the box's centre and the eye ray through the middle pixel run along
/// the grid's axes, through the box's interior, where the voxelised box integrates exactly to
/// the box's closed form (each trilinear ramp at a face adds half a cell on either side of it).
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
    let mut renderer = Renderer::new(&gpu, w, h, OUTPUT_FORMAT, &config).unwrap();
    let target = OffscreenTarget::new(&gpu, w, h);
    renderer
        .render(&gpu, &scene, &[], &RenderOptions::default(), &target.view)
        .unwrap();
    let hdr = smokeshadow::gpu::read_texture_rgba16f(&gpu, renderer.hdr_texture()).unwrap();
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
    let t = renderer.probe(&gpu, &scene, &[], &points).unwrap();
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
        let mut renderer = Renderer::new(&gpu, w, h, OUTPUT_FORMAT, &config).unwrap();
        let target = OffscreenTarget::new(&gpu, w, h);
        let err = renderer
            .render(&gpu, &scene, &[], &RenderOptions::default(), &target.view)
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
        // Down through the box, the light only falls.
        for w in line.windows(2) {
            assert!(
                w[1] <= w[0] + 2e-3,
                "{}: T rises downwards: {line:?}",
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
            assert!(
                (ground - closed).abs() < 5e-3,
                "{} at {channels}: T on the ground {ground}, closed form {closed}",
                entry.name
            );
            let sum: f32 = t.iter().zip(&exact).map(|(a, b)| (a - b).powi(2)).sum();
            (sum / t.len() as f32).sqrt()
        };
        let (coarse, fine) = (rms(4), rms(24));
        assert!(
            fine < coarse,
            "{}: RMS ΔT {fine} at 24 channels, {coarse} at 4",
            entry.name
        );
    }
}
