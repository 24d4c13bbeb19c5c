//! `smokeshadow sweep --animate`: every cell over consecutive frames against `exact` at each
//! (crate::motion). A still scene changes by nothing in any technique; the thesis plume's
//! measures agree with the frames rendered here one by one and measured by this file's own
//! arithmetic; a particle sequence moves frame by frame; bad spans get one line.

mod common;

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
    let mut renderer = Renderer::new(&gpu, 128, 96, OUTPUT_FORMAT, &config).unwrap();
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
                .unwrap();
            let rgba = smokeshadow::gpu::read_texture_rgba8(&gpu, &target.texture).unwrap();
            luminance(&image::DynamicImage::ImageRgba8(rgba).into_rgb8())
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
    assert!(
        stdout.contains("in motion, by temporal error vs exact"),
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
    let late = smokeshadow(&[
        "sweep",
        toml.to_str().unwrap(),
        "--techniques",
        "osm",
        "--animate",
        "7.9..8.1",
        "-o",
        dir.join("late").to_str().unwrap(),
    ]);
    assert!(!late.status.success());
    let lines = error_lines(&late);
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(lines[0].contains("smoke.0193.ply"), "{}", lines[0]);
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
