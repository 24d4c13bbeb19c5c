//! The command line: bad input gets one clear line and a non-zero exit, nothing half-written is
//! left behind, and `render` writes a PNG of the requested size.

mod common;

use std::process::{Command, Output};

use common::{error_lines, scratch, smokeshadow};

fn assert_one_line_error(out: &Output, needles: &[&str]) {
    let lines = error_lines(out);
    assert!(
        !out.status.success(),
        "expected failure, got {:?}",
        out.status
    );
    assert_eq!(lines.len(), 1, "one line expected, got {lines:#?}");
    for needle in needles {
        assert!(lines[0].contains(needle), "`{}` lacks `{needle}`", lines[0]);
    }
    assert!(!lines[0].contains("panicked"), "{}", lines[0]);
}

#[test]
fn bad_inputs_get_one_clear_line_and_leave_no_file() {
    let dir = scratch("cli-bad");
    let out_png = dir.join("out.png");
    let out = out_png.to_str().unwrap();
    let bad_scene = dir.join("bad.toml");
    std::fs::write(&bad_scene, "[emitter]\ncount = 0\n").unwrap();
    let syntax = dir.join("syntax.toml");
    std::fs::write(&syntax, "[camera]\nfov_y_deg = = 3\n").unwrap();
    let bad_choice = dir.join("choice.toml");
    std::fs::write(&bad_choice, "[shadow.params]\ndom_interp = \"spline\"\n").unwrap();
    let unknown = dir.join("unknown.toml");
    std::fs::write(&unknown, "[light]\ncolour = [1.0, 1.0, 1.0]\n").unwrap();
    let cases: Vec<(Vec<&str>, Vec<&str>)> = vec![
        (
            vec!["render", "/no/such.toml", "-o", out],
            vec!["/no/such.toml", "cannot read"],
        ),
        (
            vec!["render", bad_scene.to_str().unwrap(), "-o", out],
            vec!["emitter.count = 0", "1..=4000000"],
        ),
        (
            vec!["render", syntax.to_str().unwrap(), "-o", out],
            vec!["line 2", "column"],
        ),
        (
            vec!["render", unknown.to_str().unwrap(), "-o", out],
            vec!["unknown field `colour`"],
        ),
        (
            vec!["render", "--sort", "depth", "-o", out],
            vec!["--sort", "'depth'"],
        ),
        (
            vec!["bench", "--sort", "view,random", "-o", out],
            vec!["--sort", "'random'"],
        ),
        (
            vec!["render", "--technique", "magic", "-o", out],
            vec!["\"magic\"", "none", "osm"],
        ),
        (
            vec!["render", "--channels", "0", "-o", out],
            vec!["--channels 0", "1..=128"],
        ),
        (
            vec!["render", "--channels", "129", "-o", out],
            vec!["--channels 129", "1..=128"],
        ),
        (
            vec![
                "render",
                "--technique",
                "fom",
                "--channels",
                "33",
                "-o",
                out,
            ],
            vec!["--channels 33", "3..=32"],
        ),
        (
            vec!["render", "--channels", "-4", "-o", out],
            vec!["--channels"],
        ),
        (
            vec!["render", "--size", "0x100", "-o", out],
            vec!["out of range", "1..=8192"],
        ),
        (
            vec!["render", "--size", "big", "-o", out],
            vec!["WIDTHxHEIGHT"],
        ),
        (
            vec!["render", "--shadow-res", "0", "-o", out],
            vec!["--shadow-res"],
        ),
        (
            vec!["render", "--size", "64x48", "-o", "/no/such/dir/out.png"],
            vec!["does not exist"],
        ),
        (
            vec!["render", "--technique", "dom", "--channels", "1", "-o", out],
            vec!["dom", "allowed 2..=128"],
        ),
        (
            vec!["render", "--technique", "fom", "--channels", "2", "-o", out],
            vec!["fom", "allowed 3..=32"],
        ),
        (
            vec!["render", "--param", "dom_layer_growth=2000", "-o", out],
            vec!["dom_layer_growth", "1..=1000"],
        ),
        (
            vec!["render", "--param", "dom_thickness_m=-1", "-o", out],
            vec!["dom_thickness_m"],
        ),
        (
            vec!["render", "--param", "osm_interp=quadratic", "-o", out],
            vec![
                "osm_interp = \"quadratic\"",
                "not one of its choices: linear, cubic",
            ],
        ),
        (
            vec!["render", bad_choice.to_str().unwrap(), "-o", out],
            vec![
                "dom_interp = \"spline\"",
                "not one of its choices: linear, cubic",
            ],
        ),
        (
            vec!["render", "plume_scaled", "--particles", "0", "-o", out],
            vec!["--particles", "0 particles is out of range", "1..=4000000"],
        ),
        (
            vec!["render", "--particles", "lots", "-o", out],
            vec!["--particles", "\"lots\" is not a particle count"],
        ),
        (
            vec!["render", "--particles", "4000001", "-o", out],
            vec!["--particles", "1..=4000000"],
        ),
        (
            vec!["sweep", "--particles", "-3", "-o", out],
            vec!["--particles", "\"-3\" is not a particle count"],
        ),
        (
            vec!["baseline", "--check", "--particles", "5000"],
            vec!["--particles 5000 does not apply to baseline"],
        ),
        (
            vec!["bench", "--particles-list", "500,0", "-o", out],
            vec!["--particles-list", "0 particles is out of range"],
        ),
        (
            vec![
                "bench",
                "--particles",
                "500",
                "--particles-list",
                "600",
                "-o",
                out,
            ],
            vec!["--particles"],
        ),
        (
            vec!["bench", "-t", "magic", "--particles-list", "500", "-o", out],
            vec!["\"magic\"", "osm"],
        ),
        (vec!["probe", "--at", "1,2"], vec!["--at", "X,Y,Z"]),
        (
            vec![
                "probe",
                "--technique",
                "fom",
                "--channels",
                "1",
                "--at",
                "0,2,0",
            ],
            vec!["fom", "allowed 3..=32"],
        ),
    ];
    for (args, needles) in cases {
        let result = smokeshadow(&args);
        assert_one_line_error(&result, &needles);
        assert!(!out_png.exists(), "{args:?} left {out}");
    }
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !n.ends_with(".toml"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn a_missing_adapter_says_to_install_a_vulkan_driver() {
    let out = Command::new(env!("CARGO_BIN_EXE_smokeshadow"))
        .args(["render", "--size", "8x8", "-o", "/tmp/never.png"])
        .env("SMOKESHADOW_ADAPTER", "no-such-gpu-anywhere")
        .output()
        .unwrap();
    assert_one_line_error(
        &out,
        &[
            "no GPU adapter",
            "no-such-gpu-anywhere",
            "mesa-vulkan-drivers",
        ],
    );
    // The viewer says so on the terminal before any window exists.
    let out = Command::new(env!("CARGO_BIN_EXE_smokeshadow"))
        .args(["view"])
        .env("SMOKESHADOW_ADAPTER", "no-such-gpu-anywhere")
        .env_remove("DISPLAY")
        .output()
        .unwrap();
    assert_one_line_error(&out, &["no GPU adapter", "no-such-gpu-anywhere"]);
    // No Vulkan driver at all: point the loader at an empty ICD list.
    let out = Command::new(env!("CARGO_BIN_EXE_smokeshadow"))
        .args(["info"])
        .env("VK_ICD_FILENAMES", "/nonexistent/icd.json")
        .env("VK_DRIVER_FILES", "/nonexistent/icd.json")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let text = String::from_utf8_lossy(&out.stderr);
    assert!(
        text.contains("no GPU adapter found") && text.contains("lavapipe"),
        "{text}"
    );
}

#[test]
fn render_writes_a_png_of_the_requested_size() {
    let dir = scratch("cli-render");
    let png = dir.join("smoke.png");
    let out = smokeshadow(&[
        "render",
        "--technique",
        "osm",
        "--channels",
        "6",
        "--size",
        "160x120",
        "--exr",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("6 channels"), "{stdout}");
    let image = image::open(&png).unwrap().into_rgb8();
    assert_eq!((image.width(), image.height()), (160, 120));

    // The HDR frame beside it: the same picture before the tone map, so the brightest pixel of
    // one is among the brightest of the other, and the smoke's opacity is in alpha.
    let hdr = image::open(dir.join("smoke.exr")).unwrap().into_rgba32f();
    assert_eq!(hdr.dimensions(), (160, 120));
    let luma = |p: [f32; 3]| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
    let hdr_luma: Vec<f32> = hdr.pixels().map(|p| luma([p[0], p[1], p[2]])).collect();
    let png_luma: Vec<f32> = image
        .pixels()
        .map(|p| luma([p[0], p[1], p[2]].map(f32::from)))
        .collect();
    let brightest = |v: &[f32]| (0..v.len()).max_by(|&a, &b| v[a].total_cmp(&v[b])).unwrap();
    let mut sorted = png_luma.clone();
    sorted.sort_by(f32::total_cmp);
    let top_percentile = sorted[sorted.len() * 99 / 100];
    assert!(png_luma[brightest(&hdr_luma)] >= top_percentile);
    assert!(hdr.pixels().any(|p| p[3] > 0.2) && hdr.pixels().all(|p| p[3] <= 1.001));

    // An EXR cannot replace the PNG it is written beside.
    let clash = dir.join("smoke2.exr");
    let out = smokeshadow(&["render", "--exr", "-o", clash.to_str().unwrap()]);
    assert_one_line_error(&out, &["smoke2.exr", "--exr"]);
    assert!(!clash.exists());
}

#[test]
fn bench_prints_per_pass_gpu_times() {
    let dir = scratch("cli-bench");
    let png = dir.join("b.png");
    let trace = dir.join("trace.json");
    let out = smokeshadow(&[
        "render",
        "--size",
        "128x96",
        "--channels",
        "8",
        "--bench",
        "3",
        "--warmup",
        "1",
        "--trace",
        trace.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    for row in [
        "gpu shadow",
        "gpu opaque",
        "gpu particles",
        "gpu tonemap",
        "cpu sort",
        "wall frame",
    ] {
        assert!(stdout.contains(row), "`{row}` missing from:\n{stdout}");
    }

    // The trace: three frames in order, each tiled by its passes without gap or overlap.
    let trace: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&trace).unwrap()).unwrap();
    let events = trace["traceEvents"].as_array().unwrap();
    let span = |e: &serde_json::Value| (e["ts"].as_f64().unwrap(), e["dur"].as_f64().unwrap());
    let frames: Vec<(f64, f64)> = events
        .iter()
        .filter(|e| e["cat"] == "frame")
        .map(span)
        .collect();
    assert_eq!(frames.len(), 3, "{trace}");
    for (i, &(ts, dur)) in frames.iter().enumerate() {
        assert!(dur > 0.0);
        if i > 0 {
            assert!(
                ts >= frames[i - 1].0 + frames[i - 1].1 - 1e-3,
                "frames overlap"
            );
        }
        let passes: Vec<&serde_json::Value> = events
            .iter()
            .filter(|e| e["cat"] == "pass" && e["args"]["frame"] == i as u64)
            .collect();
        let mut end = ts;
        for pass in &passes {
            let (p_ts, p_dur) = span(pass);
            assert!((p_ts - end).abs() < 1e-3 && p_dur >= 0.0, "{pass}");
            end = p_ts + p_dur;
        }
        assert!((end - (ts + dur)).abs() < 1e-3 * dur.max(1.0));
        for name in ["shadow", "opaque", "particles", "tonemap"] {
            assert!(
                passes.iter().any(|p| p["name"] == name),
                "{name} in frame {i}"
            );
        }
    }
}

#[test]
fn render_works_for_every_technique() {
    let dir = scratch("cli-every-technique");
    for technique in smokeshadow::shadow::particle_techniques().map(|e| e.name) {
        let png = dir.join(format!("{technique}.png"));
        let out = smokeshadow(&[
            "render",
            "--technique",
            technique,
            "--channels",
            "5",
            "--shadow-res",
            "128",
            "--size",
            "96x72",
            "-o",
            png.to_str().unwrap(),
        ]);
        assert!(
            out.status.success(),
            "{technique}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            stdout.contains(&format!("technique {technique}")),
            "{stdout}"
        );
        assert_eq!(image::open(&png).unwrap().width(), 96);
    }
}

#[test]
fn probe_prints_the_technique_beside_exact_along_the_light() {
    let out = smokeshadow(&[
        "probe",
        "--technique",
        "osm",
        "--channels",
        "8",
        "--shadow-res",
        "128",
        "--splat",
        "segment",
        "--at",
        "0,2.5,0",
        "--along-light",
        "5",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["technique"], "osm");
    assert_eq!(report["splat"], "segment");
    let along = report["along_light"].as_array().unwrap();
    assert_eq!(along.len(), 5);
    // T starts at 1 in front of the smoke, never rises along the ray, and the plume's centre
    // is in shadow for both.
    let exact: Vec<f64> = along.iter().map(|s| s["exact"].as_f64().unwrap()).collect();
    assert!((exact[0] - 1.0).abs() < 1e-6, "{exact:?}");
    assert!(exact.windows(2).all(|w| w[1] <= w[0] + 1e-6), "{exact:?}");
    assert!(report["at"]["exact"].as_f64().unwrap() < 0.5);
    assert!(report["at"]["transmittance"].as_f64().unwrap() < 0.5);

    let table = smokeshadow(&["probe", "--shadow-res", "128", "--at", "0,2.5,0"]);
    let text = String::from_utf8_lossy(&table.stdout);
    assert!(
        text.contains("exact") && text.contains("T at (0, 2.5, 0)"),
        "{text}"
    );
}

#[test]
fn the_largest_budget_at_the_largest_resolution_renders_or_fails_in_one_line() {
    // 32 channels at 8192² asks for 4-8 GiB of maps: over the memory budget (refused before
    // allocating), beyond a binding limit (`exact`), refused by the driver inside an error
    // scope, or small enough to render (`has`'s light buffer, `none`). Never a panic, never a
    // half-written file.
    let dir = scratch("cli-largest");
    for entry in smokeshadow::shadow::particle_techniques() {
        let png = dir.join(format!("{}.png", entry.name));
        let out = smokeshadow(&[
            "render",
            "-t",
            entry.name,
            "-c",
            "32",
            "--shadow-res",
            "8192",
            "--size",
            "64x48",
            "-o",
            png.to_str().unwrap(),
        ]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!stderr.contains("panicked"), "{}: {stderr}", entry.name);
        if out.status.success() {
            assert!(png.is_file(), "{} succeeded without writing", entry.name);
            assert!(error_lines(&out).is_empty(), "{}: {stderr}", entry.name);
        } else {
            assert_eq!(out.status.code(), Some(2), "{}: {stderr}", entry.name);
            assert_one_line_error(&out, &["error:"]);
            assert!(!png.exists(), "{} left a file behind", entry.name);
        }
    }
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .filter(|n| !n.to_string_lossy().ends_with(".png"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
}

#[test]
fn every_command_takes_an_embedded_scenes_name() {
    let dir = scratch("cli-embedded-names");
    let png = dir.join("wind.png");
    let out = smokeshadow(&[
        "render",
        "thesis_wind",
        "-t",
        "osm",
        "-c",
        "4",
        "--shadow-res",
        "64",
        "--size",
        "64x48",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(png.is_file());
    let probe = smokeshadow(&["probe", "thesis_wind", "--at", "0,2,0", "--json"]);
    assert!(
        probe.status.success(),
        "{}",
        String::from_utf8_lossy(&probe.stderr)
    );
    assert!(String::from_utf8_lossy(&probe.stdout).contains("\"thesis_wind\""));
    // A gallery scene with several emitters, by name.
    let outlier = dir.join("outlier.png");
    let out = smokeshadow(&[
        "render",
        "outlier",
        "-t",
        "none",
        "--size",
        "64x48",
        "-o",
        outlier.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("2560 particles"));
    // Neither a file nor an embedded scene: the line names the embedded ones.
    let missing = smokeshadow(&["render", "thesis_breeze", "-o", png.to_str().unwrap()]);
    let hint = format!("embedded scenes: {}", smokeshadow::scene::embedded_names());
    assert!(hint.contains("thesis_plume, thesis_wind, plume_scaled, plume_65k, two_plumes"));
    assert_one_line_error(&missing, &["thesis_breeze", &hint]);
}

#[test]
fn particles_rescales_the_scene_a_command_loads() {
    let out = smokeshadow(&[
        "probe",
        "plume_scaled",
        "--particles",
        "3000",
        "--at",
        "0,2,0",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let dir = scratch("cli-particles");
    let png = dir.join("scaled.png");
    let out = smokeshadow(&[
        "render",
        "plume_scaled",
        "--particles",
        "3000",
        "-t",
        "none",
        "--size",
        "64x48",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("3000 particles simulated"), "{stdout}");
    // stderr is not a terminal here: no progress bar, nothing at all.
    assert!(
        out.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn bench_writes_a_table_csv_json_and_charts() {
    let dir = scratch("cli-bench-scaling");
    let out = smokeshadow(&[
        "bench",
        "--particles-list",
        "500,2000",
        "--frames",
        "2",
        "--warmup",
        "1",
        "-t",
        "osm",
        "-t",
        "none",
        "-t",
        "dom",
        "-c",
        "1",
        "--size",
        "96x72",
        "-o",
        dir.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("plume_scaled at 96x72"), "{stdout}");
    // dom needs 2 channels: refused with the reason, in its row, and the bench goes on.
    assert!(stdout.contains("refused"), "{stdout}");

    let mut csv = csv::Reader::from_path(dir.join("bench.csv")).unwrap();
    let header: Vec<String> = csv.headers().unwrap().iter().map(str::to_owned).collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| h == name)
            .unwrap_or_else(|| panic!("no column {name} in {header:?}"))
    };
    let rows: Vec<csv::StringRecord> = csv.records().map(Result::unwrap).collect();
    let cells: Vec<(String, String)> = rows
        .iter()
        .map(|r| {
            (
                r[col("particles")].to_owned(),
                r[col("technique")].to_owned(),
            )
        })
        .collect();
    let expected: Vec<(String, String)> = ["500", "2000"]
        .iter()
        .flat_map(|n| ["osm", "none", "dom"].map(|t| (n.to_string(), t.to_owned())))
        .collect();
    assert_eq!(cells, expected);
    let number = |r: &csv::StringRecord, name: &str| -> f64 {
        r[col(name)]
            .parse()
            .unwrap_or_else(|_| panic!("{name} = {:?} in {r:?}", &r[col(name)]))
    };
    for r in &rows {
        assert!(number(r, "sim_ms") > 0.0, "{r:?}");
        if &r[col("technique")] == "dom" {
            assert!(r[col("refused")].contains("dom"), "{r:?}");
            assert!(r[col("frame_ms_median")].is_empty(), "{r:?}");
            continue;
        }
        assert!(r[col("refused")].is_empty(), "{r:?}");
        // Every pass the renderer records was timed, and took time.
        for pass in ["opaque", "particles", "tonemap"] {
            assert!(
                number(r, &format!("gpu_{pass}_ms_median")) > 0.0,
                "{pass}: {r:?}"
            );
        }
        assert!(number(r, "frame_ms_median") > 0.0, "{r:?}");
        assert!(number(r, "sort_ms_median") >= 0.0, "{r:?}");
    }
    let osm = rows.iter().find(|r| &r[col("technique")] == "osm").unwrap();
    assert!(number(osm, "gpu_shadow_ms_median") > 0.0, "{osm:?}");
    assert!(number(osm, "bytes") > 0.0, "{osm:?}");
    // The bound of its build: at one channel osm draws what the cheapest build draws (one R16F
    // channel over the same billboards), so the counts agree; the derived columns are finite.
    for name in [
        "build_ms_median",
        "fragments",
        "channel_writes",
        "ns_per_fragment",
        "ns_per_channel_write",
        "cheapest_build_ms",
        "build_over_cheapest",
    ] {
        let v = number(osm, name);
        assert!(v.is_finite() && v > 0.0, "{name}: {osm:?}");
    }
    assert_eq!(&osm[col("fragments")], &osm[col("cheapest_fragments")]);
    // `none` builds nothing: no bound.
    let none = rows
        .iter()
        .find(|r| &r[col("technique")] == "none")
        .unwrap();
    assert!(none[col("fragments")].is_empty(), "{none:?}");

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("bench.json")).unwrap()).unwrap();
    let counts = json["counts"].as_array().unwrap();
    assert_eq!(counts.len(), 2);
    assert_eq!(counts[1]["particles"], 2000);
    assert_eq!(counts[1]["cells"].as_array().unwrap().len(), 3);
    for chart in smokeshadow::bench::CHART_FILES {
        let svg = std::fs::read_to_string(dir.join(chart)).unwrap();
        assert!(
            svg.starts_with("<svg") && svg.contains("particles (log scale)"),
            "{chart}"
        );
    }
}
