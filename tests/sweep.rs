//! `smokeshadow sweep` end to end on a tiny sweep: the files it writes, the bytes and error
//! columns, `--resume` after an interrupted run, and bad input.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use smokeshadow::sweep::SweepResults;

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// The tiny sweep: 2 techniques x 2 budgets x 1 resolution, `frames` timed frames.
fn tiny_sweep_frames(dir: &Path, frames: &str, extra: &[&str]) -> Output {
    let mut args = vec![
        "sweep",
        "--size",
        "160x120",
        "--techniques",
        "osm,fom",
        "--channels",
        "24,8",
        "--shadow-res",
        "128",
        "--frames",
        frames,
        "--warmup",
        "1",
        "-o",
        dir.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    Command::new(env!("CARGO_BIN_EXE_smokeshadow"))
        .args(&args)
        .env("SMOKESHADOW_ADAPTER", "cpu")
        .output()
        .unwrap()
}

fn tiny_sweep(dir: &Path, extra: &[&str]) -> Output {
    tiny_sweep_frames(dir, "2", extra)
}

fn ok(out: &Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// CSV rows as maps from column to value.
fn csv_rows(path: &Path) -> Vec<Vec<(String, String)>> {
    let mut reader = csv::Reader::from_path(path).unwrap();
    let header: Vec<String> = reader.headers().unwrap().iter().map(String::from).collect();
    reader
        .records()
        .map(|r| {
            header
                .iter()
                .cloned()
                .zip(r.unwrap().iter().map(String::from))
                .collect()
        })
        .collect()
}

fn get<'a>(row: &'a [(String, String)], column: &str) -> &'a str {
    &row.iter().find(|(c, _)| c == column).unwrap().1
}

#[test]
fn a_tiny_sweep_writes_consistent_tables_charts_and_a_report() {
    let dir = scratch("sweep-tiny");
    ok(&tiny_sweep(&dir, &[]));

    // One row per cell (the `none` baseline, then 2 x 2), the documented columns in order.
    let mut reader = csv::Reader::from_path(dir.join("results.csv")).unwrap();
    let header: Vec<String> = reader.headers().unwrap().iter().map(String::from).collect();
    assert_eq!(header, smokeshadow::sweep::CSV_COLUMNS);
    let rows = csv_rows(&dir.join("results.csv"));
    let cells: Vec<(&str, &str)> = rows
        .iter()
        .map(|r| (get(r, "technique"), get(r, "channels")))
        .collect();
    assert_eq!(
        cells,
        [
            ("none", "1"),
            ("osm", "24"),
            ("osm", "8"),
            ("fom", "24"),
            ("fom", "8")
        ]
    );

    let texels = 128u64 * 128;
    let params = smokeshadow::shadow::layered::PARAMS_BYTES;
    for row in &rows {
        let bytes: u64 = get(row, "bytes").parse().unwrap();
        let channels: u64 = get(row, "channels").parse().unwrap();
        // Each technique's formula: osm packs B half floats per texel, fom 2n + 1 floats
        // (4 bytes) with n = floor((B - 1) / 2), both in full RGBA targets plus a remainder of
        // 1, 2 or 4 components; and the uniform parameters.
        let packed_bytes = |packed: u64, per: u64| {
            let rest = [0, 1, 2, 4][(packed % 4) as usize];
            (packed / 4 * 4 + rest) * per
        };
        let expected = match get(row, "technique") {
            "none" => 0,
            "osm" => texels * packed_bytes(channels, 2) + params,
            "fom" => texels * packed_bytes(2 * ((channels - 1) / 2) + 1, 4) + params,
            other => panic!("unexpected technique {other}"),
        };
        assert_eq!(bytes, expected, "{row:?}");
        let overhead: f64 = get(row, "overhead_ratio").parse().unwrap();
        assert!(overhead > 0.0, "{row:?}");
        if get(row, "technique") == "none" {
            assert_eq!(get(row, "flip_vs_exact"), "");
            continue;
        }
        let flip_own: f64 = get(row, "flip_vs_own_24").parse().unwrap();
        let flip_exact: f64 = get(row, "flip_vs_exact").parse().unwrap();
        let rms_t: f64 = get(row, "rms_transmittance_error").parse().unwrap();
        if channels == 24 {
            assert_eq!(flip_own, 0.0, "{row:?}");
        } else {
            assert!(flip_own > 0.0, "{row:?}");
        }
        assert!(flip_exact > 0.0 && rms_t > 0.0, "{row:?}");
        assert!(dir.join(get(row, "image")).is_file());
    }

    let results: SweepResults =
        serde_json::from_str(&std::fs::read_to_string(dir.join("results.json")).unwrap()).unwrap();
    assert_eq!(results.cells.len(), 5);
    assert_eq!(results.metadata.scene, "thesis_plume");
    assert!(results.metadata.timestamp_queries);

    let charts: Vec<PathBuf> = std::fs::read_dir(dir.join("charts"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "svg"))
        .collect();
    assert!(charts.len() >= 3, "{charts:?}");
    for chart in &charts {
        let text = std::fs::read_to_string(chart).unwrap();
        roxmltree::Document::parse(&text)
            .unwrap_or_else(|e| panic!("{} is not valid XML: {e}", chart.display()));
    }

    let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
    let links = smokeshadow::compare::referenced_paths(&html);
    assert!(links.len() > 10, "{links:?}");
    for link in links {
        assert!(!link.is_absolute(), "{link:?}");
        assert!(
            dir.join(&link).is_file(),
            "index.html links to missing {link:?}"
        );
    }
}

#[test]
fn resume_runs_only_the_missing_cells_and_ends_with_the_same_table() {
    let full = scratch("sweep-full");
    ok(&tiny_sweep(&full, &[]));

    // An interrupted run: the same sweep, stopped after two of its cells were persisted.
    let stopped = scratch("sweep-stopped");
    ok(&tiny_sweep(&stopped, &[]));
    for cell in ["osm_8_128_point", "fom_24_128_point", "fom_8_128_point"] {
        std::fs::remove_file(stopped.join(format!("cells/{cell}.json"))).unwrap();
    }
    let out = tiny_sweep(&stopped, &["--resume"]);
    ok(&out);
    let log = String::from_utf8_lossy(&out.stderr);
    assert_eq!(log.matches("done earlier, reused").count(), 2, "{log}");
    assert!(
        log.contains("osm 8 ch") && log.contains("fom 24 ch") && log.contains("fom 8 ch"),
        "{log}"
    );

    // Timings aside, the table is the one an uninterrupted run writes.
    let timing = |c: &str| c.contains("_ms_") || c.ends_with("_ratio");
    let strip = |rows: Vec<Vec<(String, String)>>| -> Vec<Vec<(String, String)>> {
        rows.into_iter()
            .map(|r| r.into_iter().filter(|(c, _)| !timing(c)).collect())
            .collect()
    };
    assert_eq!(
        strip(csv_rows(&stopped.join("results.csv"))),
        strip(csv_rows(&full.join("results.csv")))
    );

    // Other settings do not reuse those cells.
    let out = tiny_sweep_frames(&stopped, "3", &["--resume"]);
    ok(&out);
    assert_eq!(
        String::from_utf8_lossy(&out.stderr)
            .matches("reused")
            .count(),
        0
    );
}

#[test]
fn bad_sweep_input_gets_one_line() {
    let file = scratch("sweep-file");
    std::fs::create_dir_all(file.parent().unwrap()).unwrap();
    std::fs::write(&file, "not a folder").unwrap();
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_smokeshadow"))
            .args(args)
            .env("SMOKESHADOW_ADAPTER", "cpu")
            .output()
            .unwrap()
    };
    for (args, needle) in [
        (
            vec!["sweep", "-o", file.to_str().unwrap(), "--size", "32x24"],
            "is a file",
        ),
        (
            vec!["sweep", "--techniques", "exact", "-o", "/tmp/x"],
            "reference",
        ),
        (
            vec!["sweep", "--techniques", "magic", "-o", "/tmp/x"],
            "\"magic\"",
        ),
        (vec!["sweep", "--channels", "40", "-o", "/tmp/x"], "1..=32"),
        (vec!["sweep", "--channels", "", "-o", "/tmp/x"], "channels"),
        (vec!["sweep", "--frames", "0", "-o", "/tmp/x"], "frames"),
    ] {
        let out = run(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let lines: Vec<String> = String::from_utf8_lossy(&out.stderr)
            .lines()
            .filter(|l| !l.trim().is_empty() && !l.contains("XDG_RUNTIME_DIR"))
            .map(String::from)
            .collect();
        assert_eq!(lines.len(), 1, "{args:?}: {lines:?}");
        assert!(lines[0].contains(needle), "{args:?}: {}", lines[0]);
    }
}

#[test]
fn cell_seconds_stops_each_cell_after_two_slow_timed_frames() {
    // 50 frames asked, but each cell may time for only a millisecond, which every frame outlasts
    // on its own: every cell stops at the 2 frames it then takes (3 for frames shorter than the
    // seconds: the unit test of `timed_enough`), and says so.
    let dir = scratch("sweep-cell-seconds");
    ok(&tiny_sweep_frames(&dir, "50", &["--cell-seconds", "0.001"]));
    let rows = csv_rows(&dir.join("results.csv"));
    assert!(rows.len() >= 5, "{rows:?}");
    for row in &rows {
        let frames = &row.iter().find(|(c, _)| c == "frames_timed").unwrap().1;
        assert_eq!(frames, "2", "{row:?}");
    }
    // A value that is not a positive number of seconds is refused in one line.
    let out = tiny_sweep(&scratch("sweep-cell-seconds-bad"), &["--cell-seconds", "0"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("positive number of seconds"), "{err}");
}

/// `--exr`: every cell's linear HDR frame beside its PNG, linked from the report. What the
/// files hold is checked, not only that they exist: the smoke's opacity in alpha (the same for
/// every technique, which changes only the light) and radiance that self-shadowing can only
/// lower, pixel by pixel, from the unshadowed `none` frame.
#[test]
fn exr_writes_every_cells_hdr_frame_and_the_report_links_them() {
    let dir = scratch("sweep-exr");
    ok(&tiny_sweep(&dir, &["--exr"]));
    let results: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("results.json")).unwrap()).unwrap();
    let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
    let load = |rel: &str| {
        assert!(
            html.contains(&format!("href=\"{rel}\"")),
            "{rel} not linked"
        );
        let image = image::open(dir.join(rel)).unwrap().into_rgba32f();
        assert_eq!(image.dimensions(), (160, 120), "{rel}");
        for p in image.pixels() {
            assert!(p.0.iter().all(|v| v.is_finite()), "{rel}: {p:?}");
            assert!((-1e-4..=1.0 + 1e-3).contains(&p.0[3]), "{rel}: alpha {p:?}");
        }
        image
    };
    let exact = load(results["exact_hdr_image"].as_str().unwrap());
    let alphas: Vec<f32> = exact.pixels().map(|p| p.0[3]).collect();
    assert!(alphas.iter().any(|&a| a > 0.2), "smoke somewhere");
    assert!(alphas.iter().any(|&a| a < 1e-3), "clear pixels too");
    let cells = results["cells"].as_array().unwrap();
    let none = load(cells[0]["hdr_image"].as_str().unwrap());
    for cell in &cells[1..] {
        let shadowed = load(cell["hdr_image"].as_str().unwrap());
        for (s, n) in shadowed.pixels().zip(none.pixels()) {
            assert!(
                (s.0[3] - n.0[3]).abs() < 2e-3,
                "{cell}: alpha {s:?} vs {n:?}"
            );
            for c in 0..3 {
                assert!(
                    s.0[c] <= n.0[c] * 1.002 + 1e-4,
                    "{}: {s:?} brighter than {n:?}",
                    cell["technique"]
                );
            }
        }
    }
}
