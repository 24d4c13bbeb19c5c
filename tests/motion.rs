//! `smokeshadow sweep --animate`: every cell over consecutive frames against `exact` at each
//! (crate::motion). A still scene changes by nothing in any technique; the thesis plume's
//! measures agree with the frames rendered here one by one and measured by this file's own
//! arithmetic; a particle sequence moves frame by frame; bad spans get one line.

use smokeshadow::Wait;
mod common;
#[path = "common/vdb_writer.rs"]
mod vdb_writer;

use std::path::Path;

use common::{error_lines, scratch, smokeshadow};
use smokeshadow::render::{OUTPUT_FORMAT, OffscreenTarget, RenderOptions, Renderer};
use smokeshadow::scene::Scene;
use smokeshadow::sweep::SweepResults;

fn ok(out: &std::process::Output) -> String {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn results(dir: &Path) -> SweepResults {
    serde_json::from_str(&std::fs::read_to_string(dir.join("results.json")).unwrap()).unwrap()
}

/// The thesis scene reading its particles from `file` (relative to the scene file).
fn scene_reading(file: &str, extra: &str) -> String {
    let text = smokeshadow::scene::THESIS_PLUME_TOML;
    let (a, b) = (
        text.find("[emitter]").unwrap(),
        text.find("[wind]").unwrap(),
    );
    format!(
        "{}[particles]\nfile = \"{file}\"\n{extra}\n{}",
        &text[..a],
        &text[b..]
    )
}

/// A small, quick sweep's settings.
const SMALL: &[&str] = &[
    "--size",
    "128x96",
    "--shadow-res",
    "128",
    "--frames",
    "1",
    "--warmup",
    "0",
    "--bytes-per-texel",
    "none",
];

#[test]
fn a_still_scene_changes_by_nothing_in_any_technique() {
    // The plume's particles in one file (no sequence): every frame of the span is the same.
    let dir = scratch("motion-still");
    let ply = dir.join("plume.ply");
    ok(&smokeshadow(&["particles", "-o", ply.to_str().unwrap()]));
    let toml = dir.join("still.toml");
    std::fs::write(&toml, scene_reading("plume.ply", "")).unwrap();
    let out = dir.join("sweep");
    let mut args = vec![
        "sweep",
        toml.to_str().unwrap(),
        "--techniques",
        "all",
        "--channels",
        "8",
        "--animate",
        "7.9..8.0",
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(SMALL);
    ok(&smokeshadow(&args));
    let r = results(&out);
    let motion = r.metadata.motion.as_ref().expect("an animated sweep");
    assert_eq!(motion.change.frames, 4);
    assert_eq!(motion.change.luminance, 0.0, "exact does not change");
    assert_eq!(motion.change.transmittance, 0.0);
    let mut measured = 0;
    for c in r.cells.iter().filter(|c| c.technique != "none") {
        let m = c
            .motion
            .as_ref()
            .unwrap_or_else(|| panic!("{} has motion", c.technique));
        assert_eq!(m.frames, 4, "{}", c.technique);
        for (what, v) in [
            ("temporal_error", m.temporal_error),
            ("temporal_p999", m.temporal_p999),
            ("pops_per_frame", m.pops_per_frame),
            ("t_temporal_error", m.t_temporal_error),
            ("flip_std", m.flip_std),
        ] {
            assert_eq!(v, 0.0, "{} {what} on a still scene", c.technique);
        }
        // Its still error is there all the same, the same in every frame.
        let flip = c.vs_exact.unwrap().flip_mean;
        assert!(
            (m.flip_median - flip).abs() < 1e-9,
            "{}: {} vs {flip}",
            c.technique,
            m.flip_median
        );
        measured += 1;
    }
    // Every contender that shadows particles (srm shadows density volumes only).
    assert_eq!(
        measured,
        smokeshadow::shadow::particle_techniques()
            .filter(|e| e.role == smokeshadow::shadow::Role::Contender)
            .count()
    );
    assert!(
        r.cells
            .iter()
            .all(|c| c.technique != "none" || c.motion.is_none())
    );
}

/// Linear luminance of an 8-bit sRGB image, written out here (not the tool's).
fn luminance(image: &image::RgbImage) -> Vec<f64> {
    let decode = |v: u8| {
        let c = f64::from(v) / 255.0;
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    };
    image
        .pixels()
        .map(|p| 0.2126 * decode(p[0]) + 0.7152 * decode(p[1]) + 0.0722 * decode(p[2]))
        .collect()
}

/// `technique` at `channels` rendered at each of `times` by a fresh renderer, the particles
/// simulated from t = 0 for each frame.
fn frames(technique: &str, channels: u32, times: &[f32]) -> Vec<Vec<f64>> {
    let gpu = common::gpu();
    let mut base = Scene::thesis_plume();
    base.output.width_px = 128;
    base.output.height_px = 96;
    let config = common::technique(
        technique,
        channels,
        128,
        smokeshadow::shadow::SplatMode::Segment,
    );
    let mut renderer = Renderer::new(&gpu, 128, 96, OUTPUT_FORMAT, &config)
        .wait()
        .unwrap();
    let target = OffscreenTarget::new(&gpu, 128, 96);
    times
        .iter()
        .map(|&t| {
            let scene = base.at_time(t);
            let particles = smokeshadow::sim::simulate(&scene);
            renderer
                .render(
                    &gpu,
                    &scene,
                    &particles,
                    &RenderOptions::default(),
                    &target.view,
                )
                .wait()
                .unwrap();
            luminance(&target.read_rgb(&gpu).wait().unwrap())
        })
        .collect()
}

#[test]
fn the_thesis_plume_in_motion_measures_what_its_frames_show() {
    let dir = scratch("motion-thesis");
    let mut args = vec![
        "sweep",
        "--techniques",
        "osm,dom",
        "--channels",
        "24,6",
        "--animate",
        "7.8..7.9",
        "-o",
        dir.to_str().unwrap(),
    ];
    args.extend_from_slice(SMALL);
    let stdout = ok(&smokeshadow(&args));
    // The console's span line (the per-budget "in motion, by temporal error" lines appear only
    // under budgets a cell answers, and the time budgets depend on the machine's speed).
    assert!(
        stdout.contains("in motion: every cell and exact over the 4 frames"),
        "{stdout}"
    );
    let r = results(&dir);
    let motion = r.metadata.motion.as_ref().unwrap();
    let times = motion.change.span.times();
    assert_eq!(times.len(), 4);
    assert!(motion.check_worst < smokeshadow::render::reference_check::TOLERANCE);

    // The same frames rendered one by one here, and the measures by this test's arithmetic.
    let exact = frames("exact", 1, &times);
    let osm = frames("osm", 6, &times);
    let pairs = |f: &[Vec<f64>]| -> Vec<Vec<f64>> {
        f.windows(2)
            .map(|w| w[0].iter().zip(&w[1]).map(|(a, b)| b - a).collect())
            .collect()
    };
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let exact_change = mean(
        &pairs(&exact)
            .iter()
            .map(|d| mean(&d.iter().map(|x| x.abs()).collect::<Vec<_>>()))
            .collect::<Vec<_>>(),
    );
    assert!(exact_change > 1e-5, "the plume moves: {exact_change}");
    assert!(
        (motion.change.luminance - exact_change).abs() < 1e-6 * exact_change.max(1e-3),
        "exact's change: sweep {} vs frames {exact_change}",
        motion.change.luminance
    );
    let temporal = mean(
        &pairs(&osm)
            .iter()
            .zip(pairs(&exact))
            .map(|(a, b)| {
                mean(
                    &a.iter()
                        .zip(&b)
                        .map(|(x, y)| (x - y).abs())
                        .collect::<Vec<_>>(),
                )
            })
            .collect::<Vec<_>>(),
    );
    let cell = |technique: &str, channels: u32| {
        r.cells
            .iter()
            .find(|c| c.technique == technique && c.channels == channels)
            .and_then(|c| c.motion.clone())
            .unwrap_or_else(|| panic!("{technique} {channels} has motion"))
    };
    let osm6 = cell("osm", 6);
    // The renders are lavapipe's on this machine: the same pixels, so the same mean up to the
    // f32 luminance the tool sums (1e-6 of it).
    assert!(
        (osm6.temporal_error - temporal).abs() < 1e-6,
        "osm 6's temporal error: sweep {} vs frames {temporal}",
        osm6.temporal_error
    );
    assert_eq!(osm6.flip_per_frame.len(), 4);
    assert_eq!(osm6.temporal_per_pair.len(), 3);
    // Fewer slices flicker more: osm and dom at 6 channels err more in motion than at 24.
    for t in ["osm", "dom"] {
        let (small, large) = (cell(t, 6), cell(t, 24));
        assert!(
            small.temporal_error > large.temporal_error && large.temporal_error > 0.0,
            "{t}: 6 channels {} vs 24 {}",
            small.temporal_error,
            large.temporal_error
        );
    }
    // The report says it, with its charts.
    let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
    assert!(html.contains("<h2>In motion</h2>"));
    assert!(html.contains("most stable over the span"));
    for chart in [
        "temporal_error_vs_bytes.svg",
        "flip_over_time.svg",
        "temporal_error_over_time.svg",
    ] {
        assert!(dir.join("charts").join(chart).is_file(), "{chart}");
        assert!(html.contains(chart), "{chart} in the report");
    }
    // The side-by-side: exact and the chosen cells, a frame of the span each, at half size.
    let animation = r
        .animation
        .as_ref()
        .expect("an animated sweep's side-by-side");
    assert_eq!(animation.tiles[0], "exact");
    assert!(html.contains(&animation.file));
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(dir.join(&animation.file)).unwrap(),
    ));
    let reader = decoder.read_info().unwrap();
    let info = reader.info();
    assert_eq!(info.animation_control.unwrap().num_frames, 4);
    assert_eq!(
        (info.width, info.height),
        (64 * animation.tiles.len() as u32, 48)
    );
    // The CSV has the columns, filled for every cell but `none`.
    let mut reader = csv::Reader::from_path(dir.join("results.csv")).unwrap();
    let header = reader.headers().unwrap().clone();
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    for row in reader.records() {
        let row = row.unwrap();
        let filled = !row[col("temporal_error")].is_empty();
        assert_eq!(filled, &row[col("technique")] != "none", "{row:?}");
        if filled {
            assert_eq!(&row[col("motion_frames")], "4");
            for c in [
                "temporal_p999",
                "pops_per_frame",
                "t_temporal_error",
                "flip_t_p95",
            ] {
                assert!(row[col(c)].parse::<f64>().unwrap().is_finite(), "{c}");
            }
        }
    }
}

#[test]
fn a_particle_sequence_moves_frame_by_frame_at_its_own_rate() {
    let dir = scratch("motion-sequence");
    let pattern = dir.join("smoke.%04d.ply");
    ok(&smokeshadow(&[
        "particles",
        "-o",
        pattern.to_str().unwrap(),
        "--frames",
        "189..192",
        "--fps",
        "24",
    ]));
    let toml = dir.join("sequence.toml");
    std::fs::write(
        &toml,
        scene_reading("smoke.%04d.ply", "frame_rate_hz = 24.0"),
    )
    .unwrap();
    let out = dir.join("sweep");
    let mut args = vec![
        "sweep",
        toml.to_str().unwrap(),
        "--techniques",
        "osm",
        "--channels",
        "8",
        // Frames 189..=192 at the sequence's 24 fps (no --fps).
        "--animate",
        "7.875..8.0",
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(SMALL);
    ok(&smokeshadow(&args));
    let r = results(&out);
    let motion = r.metadata.motion.as_ref().unwrap();
    assert_eq!(motion.change.span.fps, 24.0);
    assert_eq!(motion.change.frames, 4);
    assert!(
        motion.change.luminance > 0.0,
        "each frame is a file of its own"
    );
    let osm = r.cells.iter().find(|c| c.technique == "osm").unwrap();
    assert!(osm.motion.as_ref().unwrap().temporal_error > 0.0);

    // A span past the sequence's last file names the file.
    refused_past_the_last_file(&toml, "osm", "7.9..8.1", "smoke.0193.ply");
}

/// `sweep SCENE --animate SPAN` of a sequence that ends before the span: one line naming the
/// missing `file`, before anything renders.
fn refused_past_the_last_file(scene: &Path, technique: &str, span: &str, file: &str) {
    let dir = scene.parent().unwrap().join("late");
    let late = smokeshadow(&[
        "sweep",
        scene.to_str().unwrap(),
        "--techniques",
        technique,
        "--animate",
        span,
        "-o",
        dir.to_str().unwrap(),
    ]);
    assert!(!late.status.success());
    let lines = error_lines(&late);
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(lines[0].contains(file), "{}", lines[0]);
}

#[test]
fn bad_spans_get_one_line() {
    let dir = scratch("motion-bad");
    for (args, says) in [
        (
            vec!["--animate", "3..2"],
            "the end must come after the start",
        ),
        (vec!["--animate", "0..100"], "at most 240"),
        (
            vec!["--animate", "1..x"],
            "\"x\" is not a number of seconds",
        ),
        (
            vec!["--animate", "1..2", "--light-orbit", "400"],
            "--light-orbit 400 is out of range",
        ),
        (
            vec!["--animate", "1..2", "--fps", "0"],
            "--fps 0 is out of range",
        ),
    ] {
        let mut all = vec!["sweep", "-o", dir.to_str().unwrap()];
        all.extend_from_slice(&args);
        let out = smokeshadow(&all);
        assert!(!out.status.success(), "{args:?}");
        let lines = error_lines(&out);
        assert_eq!(lines.len(), 1, "{args:?}: {lines:?}");
        assert!(lines[0].contains(says), "{args:?}: {}", lines[0]);
    }
    // --fps needs --animate.
    let out = smokeshadow(&["sweep", "--fps", "30", "-o", dir.to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--animate"));
}

/// T at `points` of each of `configs` seen from `scene`'s camera (the draw order of its builds:
/// the eye's back-to-front).
fn probe_from(
    scene: &Scene,
    particles: &[smokeshadow::sim::Particle],
    configs: &[smokeshadow::render::TechniqueConfig],
    points: &[glam::Vec3],
) -> Vec<Vec<f32>> {
    common::probe_all(&common::gpu(), scene, particles, configs, points)
}

#[test]
fn an_order_independent_technique_shadows_alike_in_either_draw_order() {
    // The camera turned half way round the plume reverses the order the builds draw the
    // particles in (back to front for the eye): a technique that sums or takes minima per
    // texel gives the same T at the same points.
    let scene = common::reduced_plume();
    let particles = smokeshadow::sim::simulate(&scene);
    let mut turned = scene.clone();
    let c = &scene.camera;
    turned.camera.position = c.target
        + (c.target - c.position) * glam::Vec3::new(1.0, 0.0, 1.0)
        + glam::Vec3::Y * (c.position.y - c.target.y);
    let points: Vec<glam::Vec3> =
        smokeshadow::render::shaded::particle_lighting_points(c.position, &particles)
            .into_iter()
            .step_by(7)
            .collect();
    // A technique at 8 channels with one choice parameter set.
    let choice = |name: &str, key: &str, value: &str| {
        let mut config = common::technique(name, 8, 128, smokeshadow::shadow::SplatMode::Segment);
        config.params.values.insert(
            key.into(),
            smokeshadow::scene::ParamValue::Choice(value.into()),
        );
        config
    };
    let mut configs = Vec::new();
    for e in smokeshadow::shadow::particle_techniques() {
        // has slices along the half-angle between the view and the light: its T depends on
        // the camera by construction.
        if e.owns_particle_pass {
            continue;
        }
        configs.push(match e.name {
            // Sorted insertion: independent of the draw order (the draw order's own test below).
            "avsm" => choice("avsm", "avsm_insert", "sorted"),
            name => common::technique(
                name,
                8.max(e.min_channels),
                128,
                smokeshadow::shadow::SplatMode::Segment,
            ),
        });
    }
    // How far each may move, and why: the builds' sums are not all exact. The limits hold the
    // differences measured on the plume (December 2026) with a margin of 4 or more.
    let allowed = |name: &str| -> f32 {
        match name {
            // Fixed-point sums (exact's optical depths, the volume's voxels): bit for bit.
            "exact" | "volume" => 0.0,
            // Depth-sorted lists, sorted insertion, one exponential's min: no sum to reorder
            // (measured 0).
            "dsm" | "avsm" | "esm" | "none" => 1e-6,
            // 32-bit float sums in another order (measured 3e-7 to 1.5e-5).
            "fom" | "fom_sigma" | "tmsm" => 1e-4,
            // 32-bit sums of power moments, whose reconstruction amplifies rounding (5.7e-4).
            "msm" => 3e-3,
            // Half-float targets: each add rounds to 11 bits, over the ~100 particles a texel
            // (1.8e-3 to 2.3e-3).
            // And any technique added since: an order-independent build within half floats'
            // rounding (a technique whose T depends on the draw order fails here).
            _ => 1e-2,
        }
    };
    // Each configuration's largest |ΔT| over the points between the two draw orders.
    let moves = |configs: &[smokeshadow::render::TechniqueConfig]| -> Vec<f32> {
        let a = probe_from(&scene, &particles, configs, &points);
        let b = probe_from(&turned, &particles, configs, &points);
        a.iter()
            .zip(&b)
            .map(|(ta, tb)| {
                ta.iter()
                    .zip(tb)
                    .map(|(x, y)| (x - y).abs())
                    .fold(0.0f32, f32::max)
            })
            .collect()
    };
    for (config, w) in configs.iter().zip(moves(&configs)) {
        assert!(
            w <= allowed(&config.name),
            "{}: T moves by {w:e} when the draw order turns round (allowed {:e})",
            config.name,
            allowed(&config.name)
        );
    }
    let [single, draw] = moves(&[
        choice("osm", "osm_precision", "single"),
        choice("avsm", "avsm_insert", "draw"),
    ])[..] else {
        unreachable!("two configurations, two answers")
    };
    // In single floats osm's sums reorder within 32-bit rounding: the half floats were it.
    assert!(single <= 1e-4, "osm in single floats moves T by {single}");
    // The paper's streaming insertion, in the order the particles are drawn, depends on it
    // (measured 0.32): what a camera that turns shows as flicker.
    assert!(draw > 0.05, "avsm's draw-order insertion moves T by {draw}");
}

/// A still particle (`depth` metres from `light` along its axis, `offset` to the side, of
/// radius `radius_m` and extinction `density_per_m`): the light-ray tests' smoke.
fn on_light_axis(
    light: &smokeshadow::scene::Spotlight,
) -> impl Fn(f32, f32, f32, f32) -> smokeshadow::sim::Particle {
    use glam::Vec3;
    let (origin, axis) = (light.position, (light.target - light.position).normalize());
    let side = axis.cross(Vec3::Y).normalize();
    move |depth, offset, radius_m, density_per_m| smokeshadow::sim::Particle {
        position: origin + axis * depth + side * offset,
        velocity: Vec3::ZERO,
        age_s: 1.0,
        radius_m,
        density_per_m,
        albedo: Vec3::splat(0.8),
    }
}

#[test]
fn a_particle_crossing_an_opacity_slice_steps_the_shadow_where_exact_stays_smooth() {
    use smokeshadow::sim::Particle;
    let scene = common::reduced_plume();
    let light = &scene.light;
    let axis = (light.target - light.position).normalize();
    let at = on_light_axis(light);
    // Two still particles off the point's ray fix the light's depth range (near the light and
    // far from it); one moves along the ray towards the point, always wholly in front of it,
    // so the exact optical depth at the point is the same in every frame: τ · 2r = 2.
    let point = light.position + axis * 6.0;
    let frames: Vec<Vec<Particle>> = (0..16)
        .map(|k| {
            let gap = 0.8 - 0.75 * k as f32 / 15.0;
            vec![
                at(4.0, 1.5, 0.3, 2.0),
                at(8.0, -1.5, 0.3, 2.0),
                at(6.0 - 0.2 - gap, 0.0, 0.2, 5.0),
            ]
        })
        .collect();
    let configs = [
        common::technique("exact", 1, 128, smokeshadow::shadow::SplatMode::Segment),
        common::technique("osm", 8, 128, smokeshadow::shadow::SplatMode::Segment),
        common::technique("dom", 8, 128, smokeshadow::shadow::SplatMode::Segment),
    ];
    let gpu = common::gpu();
    let series: Vec<Vec<f32>> = frames
        .iter()
        .map(|p| {
            common::probe_all(&gpu, &scene, p, &configs, &[point])
                .into_iter()
                .map(|t| t[0])
                .collect()
        })
        .collect();
    let spread = |i: usize| {
        let v: Vec<f32> = series.iter().map(|s| s[i]).collect();
        let (lo, hi) = v
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), &x| {
                (l.min(x), h.max(x))
            });
        (hi - lo, v)
    };
    let (exact, exact_t) = spread(0);
    let (osm, osm_t) = spread(1);
    let (dom, _) = spread(2);
    // exact: e^-2 in every frame (the closed form written above: τ · 2r through the centre).
    assert!(exact < 1e-5, "exact moves by {exact}");
    assert!(
        (exact_t[0] - (-2.0f32).exp()).abs() < 1e-4,
        "{}",
        exact_t[0]
    );
    // osm: once the particle's chord enters the point's slice, the slice's interpolation
    // counts only part of it: T climbs (0.149 -> 0.219 at 8 slices, measured).
    assert!(osm > 0.04, "osm moves by {osm}: {osm_t:?}");
    assert!(osm_t[15] > osm_t[0] + 0.04, "{osm_t:?}");
    // dom: its layers start at the particle, so they move with it (0.003, measured).
    assert!(dom < 0.2 * osm, "dom moves by {dom}, osm by {osm}");
}

#[test]
fn the_procedural_cloud_drifts_on_its_wind() {
    // The embedded cloud (a 16 m/s wind) over a minute, one frame every 20 s: its noise moves
    // 320 m a frame through the layer, and every cell changes with it.
    let dir = scratch("motion-cloud");
    let mut args = vec![
        "sweep",
        "cloud",
        "--techniques",
        "volume",
        "--channels",
        "8",
        "--animate",
        "0..60",
        "--fps",
        "0.05",
        "-o",
        dir.to_str().unwrap(),
    ];
    args.extend_from_slice(SMALL);
    ok(&smokeshadow(&args));
    let r = results(&dir);
    let motion = r.metadata.motion.as_ref().unwrap();
    assert_eq!(motion.change.frames, 4);
    assert!(
        motion.change.luminance > 1e-3,
        "{}",
        motion.change.luminance
    );
    assert!(motion.check_worst < smokeshadow::render::reference_check::TOLERANCE);
    let volume = r.cells.iter().find(|c| c.technique == "volume").unwrap();
    let m = volume.motion.as_ref().unwrap();
    // It follows the drift: its change differs from exact's by less than exact changes.
    assert!(
        m.temporal_error > 0.0 && m.temporal_error < motion.change.luminance,
        "{} vs exact's {}",
        m.temporal_error,
        motion.change.luminance
    );
}

#[test]
fn a_volume_sequence_moves_frame_by_frame() {
    // Four OpenVDB files of a 16³-voxel block (0.05 m voxels) that moves 8 voxels along x a
    // frame, at the sequence's 24 fps from t = 0.
    let dir = scratch("motion-vdb-sequence");
    for frame in 0..4 {
        let mut grid = vdb_writer::Grid::float("density");
        grid.map = vdb_writer::Map::UniformScale(0.05);
        for (x, y, z) in [
            (0, 0, 0),
            (8, 0, 0),
            (0, 8, 0),
            (8, 8, 0),
            (0, 0, 8),
            (8, 0, 8),
            (0, 8, 8),
            (8, 8, 8),
        ] {
            grid.leaves
                .push(vdb_writer::leaf([x + 8 * frame, y, z], |_| true, |_| 1.0));
        }
        let mut stats = vdb_writer::Stats::default();
        std::fs::write(
            dir.join(format!("block.{frame:04}.vdb")),
            vdb_writer::write_file(&[grid], &mut stats),
        )
        .unwrap();
    }
    let text = smokeshadow::scene::THESIS_PLUME_TOML;
    let (a, b) = (
        text.find("[emitter]").unwrap(),
        text.find("[wind]").unwrap(),
    );
    let scene = format!(
        "{}[volume]\nfile = \"block.%04d.vdb\"\ndensity_scale_per_m = 4.0\ntranslate_m = [-0.6, 1.0, -0.4]\n\n{}",
        &text[..a],
        &text[b..]
    )
    .replace("duration_s = 8.0", "duration_s = 0.0");
    let toml = dir.join("block.toml");
    std::fs::write(&toml, scene).unwrap();
    let out = dir.join("sweep");
    let mut args = vec![
        "sweep",
        toml.to_str().unwrap(),
        "--techniques",
        "volume",
        "--channels",
        "8",
        "--animate",
        "0..0.125",
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(SMALL);
    let stdout = ok(&smokeshadow(&args));
    let r = results(&out);
    let motion = r.metadata.motion.as_ref().unwrap();
    assert_eq!((motion.change.frames, motion.change.span.fps), (4, 24.0));
    assert!(motion.change.luminance > 1e-4, "the block moves: {stdout}");
    assert!(motion.check_worst < smokeshadow::render::reference_check::TOLERANCE);
    // Past the last file: named before anything renders.
    refused_past_the_last_file(&toml, "volume", "0..0.2", "block.0004.vdb");
}

#[test]
fn a_gallery_in_motion_ranks_each_scenes_cells_by_temporal_error_too() {
    let dir = scratch("motion-gallery");
    let mut args = vec![
        "sweep",
        "--scenes",
        "two_plumes,thesis_wind",
        "--techniques",
        "osm,dom,volume",
        "--channels",
        "8",
        "--animate",
        "7.8..7.9",
        "-o",
        dir.to_str().unwrap(),
    ];
    args.extend_from_slice(SMALL);
    let stdout = ok(&smokeshadow(&args));
    assert!(stdout.contains("in motion"), "{stdout}");
    let gallery: smokeshadow::sweep::gallery::GalleryResults =
        serde_json::from_str(&std::fs::read_to_string(dir.join("results.json")).unwrap()).unwrap();
    // Each scene's motion ranks are its cells ordered by temporal error.
    for scene in &gallery.scenes {
        let ranks: Vec<_> = gallery
            .gallery
            .ranks
            .iter()
            .filter(|r| r.scene == scene.metadata.scene)
            .collect();
        assert_eq!(ranks.len(), 3);
        let mut by_motion: Vec<_> = ranks.iter().collect();
        by_motion.sort_by_key(|r| r.motion_rank.unwrap());
        for w in by_motion.windows(2) {
            assert!(w[0].temporal_error.unwrap() <= w[1].temporal_error.unwrap());
        }
        for r in &ranks {
            let cell = scene
                .cells
                .iter()
                .find(|c| c.technique == r.technique)
                .unwrap();
            assert_eq!(
                r.temporal_error,
                cell.motion.as_ref().map(|m| m.temporal_error)
            );
        }
    }
    // The ranking gives each technique the median of its two scenes' motion ranks.
    for row in &gallery.gallery.ranking {
        let mine: Vec<f64> = gallery
            .gallery
            .ranks
            .iter()
            .filter(|r| r.technique == row.technique)
            .map(|r| f64::from(r.motion_rank.unwrap()))
            .collect();
        assert_eq!(row.motion_median_rank, Some((mine[0] + mine[1]) / 2.0));
    }
    let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
    assert!(html.contains("median rank in motion"));
}

#[test]
fn the_shadows_history_blends_each_particles_t_with_its_last_as_the_closed_form_says() {
    use smokeshadow::shadow::SplatMode;
    use smokeshadow::sim::Particle;
    const W: f32 = 0.9;
    let mut scene = common::reduced_plume();
    let at = on_light_axis(&scene.light);
    // Two still particles fix the light's depth range; the lit one (index 2) sits on the axis;
    // the blocker (index 3) starts off the axis and from frame 1 on stands in front of the lit
    // one: its T steps down at frame 1 and stays.
    let frame = |k: usize| {
        let offset = if k == 0 { 1.2 } else { 0.0 };
        vec![
            at(4.0, 1.5, 0.3, 2.0),
            at(8.0, -1.5, 0.3, 2.0),
            at(6.5, 0.0, 0.25, 2.0),
            at(5.6, offset, 0.3, 3.0),
        ]
    };
    let (w, h) = (scene.output.width_px, scene.output.height_px);
    let gpu = common::gpu();
    let target = OffscreenTarget::new(&gpu, w, h);
    let lit_t = |renderer: &mut Renderer, scene: &Scene, particles: &[Particle]| -> [f32; 4] {
        renderer
            .render(
                &gpu,
                scene,
                particles,
                &RenderOptions::default(),
                &target.view,
            )
            .wait()
            .unwrap();
        let lit = renderer.lit_particles(&gpu).wait().unwrap();
        let p = particles[2].position;
        lit.iter()
            .find(|l| l.center.distance(p) < 1e-5)
            .expect("the lit particle")
            .transmittance
    };
    let dom = common::technique("dom", 8, 128, SplatMode::Segment);
    let mut renderer = Renderer::new(&gpu, w, h, OUTPUT_FORMAT, &dom)
        .wait()
        .unwrap();
    // The same technique unfiltered, frame by frame: the T the history is fed.
    let frames = 8;
    let raw: Vec<[f32; 4]> = (0..frames)
        .map(|k| lit_t(&mut renderer, &scene, &frame(k)))
        .collect();
    assert!(
        raw[0][0] - raw[1][0] > 0.2,
        "the blocker steps T down: {raw:?}"
    );

    scene.shadow.history = W;
    renderer.reset_history();
    // A probe before the first filtered frame lights nothing: that frame still has no history.
    renderer
        .probe(&gpu, &scene, &frame(0), &[scene.light.target])
        .wait()
        .unwrap();
    let mut expected = raw[0];
    for (k, raw) in raw.iter().enumerate() {
        let particles = frame(k);
        let filtered = lit_t(&mut renderer, &scene, &particles);
        // T'_0 = T_0 (no history yet), then T'_k = (1 − w) T_k + w T'_k−1.
        if k > 0 {
            expected = std::array::from_fn(|i| (1.0 - W) * raw[i] + W * expected[i]);
        }
        for i in 0..4 {
            assert!(
                (filtered[i] - expected[i]).abs() < 1e-5,
                "frame {k} point {i}: {} vs the closed form {}",
                filtered[i],
                expected[i]
            );
        }
        // The probe at the lit particle's points gives the T the frame used.
        let eye = scene.camera.position;
        let points = smokeshadow::render::shaded::particle_lighting_points(eye, &particles[2..3]);
        let probed = renderer
            .probe_shaded(&gpu, &scene, &particles, &points, &[2; 4])
            .wait()
            .unwrap();
        assert_eq!(probed, filtered.to_vec(), "frame {k}");
    }
    // The lag: a step's remainder after k frames is w^k of it (the frames after the first
    // are alike).
    let remainder = (expected[0] - raw[1][0]) / (raw[0][0] - raw[1][0]);
    assert!(
        (remainder - W.powi(frames as i32 - 1)).abs() < 1e-4,
        "{remainder}"
    );

    // A particle reborn in its slot (its age went down) takes its T as it is.
    let mut reborn = frame(frames);
    reborn[2].age_s = 0.1;
    let t = lit_t(&mut renderer, &scene, &reborn);
    let mut renderer_raw = Renderer::new(&gpu, w, h, OUTPUT_FORMAT, &dom)
        .wait()
        .unwrap();
    let mut unfiltered = scene.clone();
    unfiltered.shadow.history = 0.0;
    assert_eq!(t, lit_t(&mut renderer_raw, &unfiltered, &reborn));

    // The reference is never filtered: exact's frames are the same with and without.
    let exact = common::technique("exact", 1, 128, SplatMode::Segment);
    renderer.set_technique(&gpu, &exact).wait().unwrap();
    renderer_raw.set_technique(&gpu, &exact).wait().unwrap();
    for k in 0..3 {
        assert_eq!(
            lit_t(&mut renderer, &scene, &frame(k)),
            lit_t(&mut renderer_raw, &unfiltered, &frame(k)),
            "exact at frame {k}"
        );
    }
}
