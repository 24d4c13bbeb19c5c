//! `smokeshadow sweep` end to end on a tiny sweep: the files it writes, the bytes and error
//! columns, `--resume` after an interrupted run, and bad input.

use smokeshadow::Wait;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use smokeshadow::sweep::SweepResults;

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// The tiny sweep's settings: 2 techniques x 2 budgets x 1 resolution, one warm-up frame.
const TINY: &[&str] = &[
    "--size",
    "160x120",
    "--techniques",
    "osm,fom",
    "--channels",
    "24,8",
    "--shadow-res",
    "128",
    "--warmup",
    "1",
    // The thesis' channel view alone (byte budgets: their own test below).
    "--bytes-per-texel",
    "none",
];

/// The tiny sweep into `dir` with `frames` timed frames.
fn tiny_sweep_frames(dir: &Path, frames: &str, extra: &[&str]) -> Output {
    let mut args = vec!["sweep"];
    args.extend_from_slice(TINY);
    args.extend_from_slice(&["--frames", frames, "-o", dir.to_str().unwrap()]);
    args.extend_from_slice(extra);
    smokeshadow(&args).output().unwrap()
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
        let bytes: u64 = get(row, "resident_bytes").parse().unwrap();
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
    // The report states the framing and the filtering every technique shares, with the texels
    // that hold smoke as results.csv counts them (the same at every cell of one resolution).
    let smoke: Vec<&str> = rows.iter().map(|r| get(r, "smoke_texels")).collect();
    assert!(smoke.windows(2).all(|w| w[0] == w[1]), "{smoke:?}");
    assert!(smoke[0].parse::<u64>().unwrap() > 0);
    assert!(
        html.contains("No technique prefilters")
            && html.contains(&format!("{} of a", smoke[0]))
            && html.contains("fitted to the smoke"),
        "the report states the footing"
    );
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
    for cell in [
        "osm_8_128_segment",
        "fom_24_128_segment",
        "fom_8_128_segment",
    ] {
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

/// `--memory`: at each resolution every technique's cell holds at most the total, and the answer
/// names each technique once: at the resolution `tune` chose (a parameter file's `[shapes]`:
/// here `osm` at 64² for 256 KiB, whatever is most accurate on this scene), else at its most
/// accurate resolution, marked "best here", as the table has it.
#[test]
fn memory_budgets_give_each_technique_its_tuned_or_best_resolution_within_the_total() {
    let dir = scratch("sweep-memory");
    let params = dir.with_extension("toml");
    std::fs::create_dir_all(params.parent().unwrap()).unwrap();
    std::fs::write(
        &params,
        "[shapes.osm]\n262144 = { resolution = 64, training = 0.01 }\n",
    )
    .unwrap();
    let out = smokeshadow(&[
        "sweep",
        "--size",
        "160x120",
        "--techniques",
        "osm,dom",
        "--channels",
        "8",
        "--shadow-res",
        "64,128",
        "--memory",
        "256KiB,48KiB",
        "--params",
        params.to_str().unwrap(),
        "--warmup",
        "0",
        "--frames",
        "1",
        "-o",
        dir.to_str().unwrap(),
    ])
    .output()
    .unwrap();
    ok(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let rows = csv_rows(&dir.join("results.csv"));
    for total in [256u64 << 10, 48 << 10] {
        let cells: Vec<&Vec<(String, String)>> = rows
            .iter()
            .filter(|r| {
                get(r, "memory_budgets")
                    .split(';')
                    .any(|b| b == total.to_string())
            })
            .collect();
        // osm and dom at 64² and 128² (48 KiB is 3 bytes a texel at 128²: dom's smallest holds
        // 4, so it answers at 64² alone).
        let expected = if total == 256 << 10 { 4 } else { 3 };
        assert_eq!(cells.len(), expected, "{total}: {cells:?}");
        for c in &cells {
            let resident: u64 = get(c, "resident_bytes").parse().unwrap();
            assert!(resident <= total, "{total}: {c:?}");
        }
        // The stdout answer: each technique once, at tune's resolution where the file has one,
        // else at its best FLIP of its cells, marked.
        let line = stdout
            .lines()
            .find(|l| l.starts_with(&format!("at {} in all", smokeshadow::report::bytes(total))))
            .unwrap_or_else(|| panic!("no answer line for {total}:\n{stdout}"));
        for technique in ["osm", "dom"] {
            let tuned = technique == "osm" && total == 256 << 10;
            let named_cell = cells
                .iter()
                .filter(|c| get(c, "technique") == technique)
                .filter(|c| !tuned || get(c, "shadow_res") == "64")
                .min_by(|a, b| {
                    let f =
                        |r: &Vec<(String, String)>| get(r, "flip_vs_exact").parse::<f64>().unwrap();
                    f(a).total_cmp(&f(b))
                })
                .unwrap();
            let named = format!(
                "{technique} {} at {}²{} (",
                get(named_cell, "channels"),
                get(named_cell, "shadow_res"),
                if tuned { "" } else { " best here" }
            );
            assert_eq!(line.matches(&format!("{technique} ")).count(), 1, "{line}");
            assert!(line.contains(&named), "{line} lacks {named}");
        }
    }
    assert!(
        stdout.contains("skipped dom at 48.0 KiB at 128²"),
        "{stdout}"
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
        (vec!["sweep", "--memory", "12", "-o", "/tmp/x"], "\"12\""),
        (
            vec!["sweep", "--memory", "1.5B", "-o", "/tmp/x"],
            "whole bytes",
        ),
        (
            vec!["sweep", "--channels", "300", "-o", "/tmp/x"],
            "1..=240",
        ),
        (vec!["sweep", "--channels", "", "-o", "/tmp/x"], "channels"),
        (vec!["sweep", "--frames", "0", "-o", "/tmp/x"], "frames"),
        (
            vec!["sweep", "--scenes", "thesis_plume,magic", "-o", "/tmp/x"],
            "--scenes magic",
        ),
        (
            vec!["sweep", "thesis_plume", "--scenes", "thesis_wind"],
            "cannot be used with",
        ),
        (vec!["sweep", "--shard", "3/3"], "K must be below N"),
        (vec!["sweep", "--shard", "1"], "is not K/N"),
        (
            vec!["sweep", "--merge", "/nonexistent/shards", "-o", "/tmp/x"],
            "no such folder",
        ),
        (
            vec![
                "sweep",
                "--merge",
                "/tmp/shards",
                "--frames",
                "3",
                "-o",
                "/tmp/x",
            ],
            "cannot be used with",
        ),
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

/// The two-scene sweep the gallery and shard tests share: the tiny sweep over `thesis_plume`
/// and `thesis_wind`.
fn two_scene_args() -> Vec<&'static str> {
    let mut args = vec!["--scenes", "thesis_plume,thesis_wind", "--frames", "2"];
    args.extend_from_slice(TINY);
    args
}

fn smokeshadow(args: &[&str]) -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_smokeshadow"));
    command.args(args).env("SMOKESHADOW_ADAPTER", "cpu");
    command
}

/// `sweep` with the two-scene settings and `extra`.
fn two_scenes(extra: &[&str]) -> Command {
    let mut args = vec!["sweep"];
    args.extend(two_scene_args());
    args.extend_from_slice(extra);
    smokeshadow(&args)
}

/// The two-scene sweep run by one process, once per test binary; its folder and stdout.
fn one_process_reference() -> &'static (PathBuf, String) {
    static REFERENCE: std::sync::OnceLock<(PathBuf, String)> = std::sync::OnceLock::new();
    REFERENCE.get_or_init(|| {
        let dir = scratch("sweep-two-scenes");
        let out = two_scenes(&["-o", dir.to_str().unwrap()]).output().unwrap();
        ok(&out);
        (dir, String::from_utf8_lossy(&out.stdout).into_owned())
    })
}

/// A CSV's rows without the columns that are times or ratios of times, which differ between
/// runs; everything else (bytes, errors, image paths) must not.
fn untimed(path: &Path) -> Vec<Vec<(String, String)>> {
    let timing = |c: &str| c.contains("_ms_") || c.ends_with("_ratio") || c == "frames_timed";
    csv_rows(path)
        .into_iter()
        .map(|r| r.into_iter().filter(|(c, _)| !timing(c)).collect())
        .collect()
}

/// Asserts that the sweep in `dir` has the one-process reference's tables (times aside): the
/// gallery's, each scene's, and the ranking.
fn same_tables_as_one_process(dir: &Path) {
    let (reference, _) = one_process_reference();
    for table in [
        "results.csv",
        "thesis_plume/results.csv",
        "thesis_wind/results.csv",
    ] {
        let (got, want) = (untimed(&dir.join(table)), untimed(&reference.join(table)));
        assert_eq!(got.len(), want.len(), "{table}");
        for (g, w) in got.iter().zip(&want) {
            assert_eq!(g, w, "{table}");
        }
    }
    assert_eq!(
        std::fs::read_to_string(dir.join("ranking.csv")).unwrap(),
        std::fs::read_to_string(reference.join("ranking.csv")).unwrap()
    );
}

/// Every link of `dir/index.html` resolves inside `dir`.
fn links_resolve(dir: &Path) {
    let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
    for link in smokeshadow::compare::referenced_paths(&html) {
        assert!(!link.is_absolute(), "{link:?}");
        assert!(
            dir.join(&link).is_file(),
            "{}: missing {link:?}",
            dir.display()
        );
    }
}

#[test]
fn scenes_sweep_writes_each_scene_and_a_gallery_whose_ranking_follows_from_its_csv() {
    let (dir, stdout) = one_process_reference();
    for scene in ["thesis_plume", "thesis_wind"] {
        let rows = csv_rows(&dir.join(scene).join("results.csv"));
        assert_eq!(rows.len(), 5, "{scene}");
        links_resolve(&dir.join(scene));
        // The gallery's CSV holds the scene's rows, behind a `scene` column, its paths
        // relative to the gallery.
        let gallery: Vec<Vec<(String, String)>> = csv_rows(&dir.join("results.csv"))
            .into_iter()
            .filter(|r| get(r, "scene") == scene)
            .map(|r| {
                r.into_iter()
                    .filter(|(c, _)| c != "scene")
                    .map(|(c, v)| match c.as_str() {
                        "image" => (c, v.strip_prefix(&format!("{scene}/")).unwrap().to_owned()),
                        _ => (c, v),
                    })
                    .collect()
            })
            .collect();
        assert_eq!(gallery, rows, "{scene}");
    }
    links_resolve(dir);

    // The ranks, recomputed from the gallery CSV: within each scene and budget, by FLIP vs exact,
    // fewer bytes first on a tie; `none` not ranked.
    let rows = csv_rows(&dir.join("results.csv"));
    let mut expected: Vec<(String, u32, String, u32)> = Vec::new();
    for scene in ["thesis_plume", "thesis_wind"] {
        for budget in [24u32, 8] {
            let mut at: Vec<&Vec<(String, String)>> = rows
                .iter()
                .filter(|r| get(r, "scene") == scene && get(r, "technique") != "none")
                .filter(|r| get(r, "channels") == budget.to_string())
                .collect();
            let key = |r: &Vec<(String, String)>| {
                (
                    get(r, "flip_vs_exact").parse::<f64>().unwrap(),
                    get(r, "resident_bytes").parse::<u64>().unwrap(),
                )
            };
            at.sort_by(|a, b| key(a).partial_cmp(&key(b)).unwrap());
            assert_eq!(at.len(), 2);
            for (i, r) in at.iter().enumerate() {
                expected.push((
                    scene.into(),
                    budget,
                    get(r, "technique").into(),
                    i as u32 + 1,
                ));
            }
        }
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("results.json")).unwrap()).unwrap();
    let mut written: Vec<(String, u32, String, u32)> = json["ranks"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            (
                r["scene"].as_str().unwrap().into(),
                r["channels"].as_u64().unwrap() as u32,
                r["technique"].as_str().unwrap().into(),
                r["rank"].as_u64().unwrap() as u32,
            )
        })
        .collect();
    written.sort();
    expected.sort();
    assert_eq!(written, expected);

    // The aggregate: median and worst rank across the two scenes, sorted by them.
    let ranking = csv_rows(&dir.join("ranking.csv"));
    assert_eq!(ranking.len(), 4, "{ranking:?}");
    let mut previous = (0.0, 0);
    for row in &ranking {
        let ranks: Vec<u32> = expected
            .iter()
            .filter(|(_, b, t, _)| {
                *t == get(row, "technique") && format!("{b} channels") == get(row, "budget")
            })
            .map(|e| e.3)
            .collect();
        assert_eq!(ranks.len(), 2, "{row:?}");
        let median = (ranks[0] + ranks[1]) as f64 / 2.0;
        let worst = *ranks.iter().max().unwrap();
        assert_eq!(get(row, "median_rank").parse::<f64>().unwrap(), median);
        assert_eq!(get(row, "worst_rank").parse::<u32>().unwrap(), worst);
        assert!((median, worst) >= previous, "not sorted: {ranking:?}");
        previous = (median, worst);
    }

    // The page: the advice names each scene's winner at each budget, as ranked.
    let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
    for scene in ["thesis_plume", "thesis_wind"] {
        assert!(
            html.contains(&format!("href=\"{scene}/index.html\"")),
            "{scene}"
        );
        let winner = &expected
            .iter()
            .find(|e| e.0 == scene && e.1 == 8 && e.3 == 1)
            .unwrap()
            .2;
        // Each scene is said in its own words (the thesis scenes: their header's sentence).
        let summary = smokeshadow::scene::Scene::embedded(scene)
            .unwrap()
            .summary();
        let like = format!("{scene} ({})", summary.trim_end_matches('.'));
        assert!(!summary.is_empty(), "{scene}");
        assert!(
            html.contains(&format!("For smoke like {like}: at 24 channels"))
                && html.contains(&format!("at 8 channels {winner} is the most accurate")),
            "{scene}: {html}"
        );
    }
    assert!(html.contains("Where each technique wins"));
    // stdout ends with the aggregate ranking table.
    let last = stdout.lines().last().unwrap();
    let row = ranking.last().unwrap();
    assert!(
        last.starts_with(get(row, "technique")) && last.contains(get(row, "worst_scene")),
        "{last}"
    );
}

/// The cells of a sweep folder, by scene.
fn cells_of(dir: &Path, scene: &str) -> Vec<serde_json::Value> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir.join(scene).join("cells"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .filter(|p| !p.file_name().unwrap().to_string_lossy().starts_with('.'))
        .collect();
    paths.sort();
    paths
        .iter()
        .map(|p| serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap())
        .collect()
}

#[test]
fn three_concurrent_shards_in_one_folder_merge_to_the_one_process_tables() {
    let shared = scratch("sweep-shards-shared");
    let children: Vec<_> = (0..3)
        .map(|k| {
            two_scenes(&["--shard", &format!("{k}/3"), "-o", shared.to_str().unwrap()])
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for child in children {
        ok(&child.wait_with_output().unwrap());
    }
    // No shard deleted another's cells, and none wrote the tables.
    assert!(!shared.join("results.csv").exists());
    for scene in ["thesis_plume", "thesis_wind"] {
        let cells = cells_of(&shared, scene);
        assert_eq!(cells.len(), 5, "{scene}");
        for cell in &cells {
            // Each cell's overhead is against the `none` its own process measured.
            let against = &cell["measured_against"];
            assert!(against["shard"]["n"] == 3, "{cell}");
            let none = against["none_frame_ms"].as_f64().unwrap();
            assert!(none > 0.0, "{cell}");
        }
    }
    for k in 0..3 {
        let manifest: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(shared.join(format!("shards/{k}-of-3.json"))).unwrap(),
        )
        .unwrap();
        assert_eq!(manifest["finished"], true);
    }

    // Merged elsewhere, with an adapter that does not exist: merging creates no GPU device.
    let merged = scratch("sweep-shards-merged");
    let out = smokeshadow(&[
        "sweep",
        "--merge",
        shared.to_str().unwrap(),
        "-o",
        merged.to_str().unwrap(),
    ])
    .env("SMOKESHADOW_ADAPTER", "no-such-adapter")
    .output()
    .unwrap();
    ok(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        !stdout.contains("note:"),
        "one machine, one exact: {stdout}"
    );
    same_tables_as_one_process(&merged);
    links_resolve(&merged);
    links_resolve(&merged.join("thesis_wind"));
    let results: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(merged.join("results.json")).unwrap())
            .unwrap();
    for scene in results["scenes"].as_array().unwrap() {
        for cell in scene["cells"].as_array().unwrap() {
            let ratio = cell["overhead_ratio"].as_f64().unwrap();
            let frame = cell["frame_ms"]["median"].as_f64().unwrap();
            let none = cell["measured_against"]["none_frame_ms"].as_f64().unwrap();
            assert!((ratio - frame / none).abs() < 1e-9, "{cell}");
        }
    }

    // A cell compared with another exact image (as a shard on another CPU would be) is
    // merged, with a note saying so.
    let cells = merged.join("thesis_wind/cells");
    let first = std::fs::read_dir(&cells)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| {
            std::fs::read_to_string(p)
                .unwrap()
                .contains("exact_image_sha256")
        })
        .unwrap();
    let mut cell: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&first).unwrap()).unwrap();
    cell["measured_against"]["exact_image_sha256"] = serde_json::json!("0".repeat(64));
    std::fs::write(&first, serde_json::to_string(&cell).unwrap()).unwrap();
    let remerged = scratch("sweep-shards-remerged");
    let out = smokeshadow(&[
        "sweep",
        "--merge",
        merged.to_str().unwrap(),
        "-o",
        remerged.to_str().unwrap(),
    ])
    .output()
    .unwrap();
    ok(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("note: thesis_wind's cells were compared with 2 different exact images"),
        "{stdout}"
    );

    // `--resume` without `--shard` over the shared folder re-measures nothing and writes the
    // whole report.
    let out = two_scenes(&["--resume", "-o", shared.to_str().unwrap()])
        .output()
        .unwrap();
    ok(&out);
    let log = String::from_utf8_lossy(&out.stderr);
    assert_eq!(log.matches("done earlier, reused").count(), 10, "{log}");
    assert!(!log.contains("exact reference"), "{log}");
    same_tables_as_one_process(&shared);
}

#[test]
fn a_shard_killed_part_way_and_resumed_finishes_the_same() {
    let dir = scratch("sweep-shards-killed");
    let shard = |k: u32, extra: &[&str]| {
        let mut args = vec!["--shard".to_owned(), format!("{k}/3")];
        args.extend(extra.iter().map(|s| s.to_string()));
        args.extend(["-o".to_owned(), dir.to_str().unwrap().to_owned()]);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        two_scenes(&args)
    };
    // Shard 1 owns cells 1, 4 (of thesis_plume), 7 (thesis_wind): kill it once its first cell
    // file appears.
    let mut child = shard(1, &[])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let first = dir.join("thesis_plume/cells/osm_24_128_segment.json");
    let start = std::time::Instant::now();
    while !first.exists() {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the shard ended before its first cell"
        );
        assert!(start.elapsed().as_secs() < 300, "no cell after 300 s");
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    child.kill().unwrap();
    assert!(!child.wait().unwrap().success());
    assert!(
        !dir.join("thesis_wind/cells/osm_8_128_segment.json")
            .exists(),
        "killed after its last cell"
    );
    let manifest = std::fs::read_to_string(dir.join("shards/1-of-3.json")).unwrap();
    assert!(manifest.contains("\"finished\": false"), "{manifest}");

    // Merging now names the missing cells and their shard, in one line.
    let (out_0, out_2) = (
        shard(0, &[]).output().unwrap(),
        shard(2, &[]).output().unwrap(),
    );
    ok(&out_0);
    ok(&out_2);
    let merged = scratch("sweep-shards-killed-merged");
    let merge = || {
        smokeshadow(&[
            "sweep",
            "--merge",
            dir.to_str().unwrap(),
            "-o",
            merged.to_str().unwrap(),
        ])
        .output()
        .unwrap()
    };
    let out = merge();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(
        err.contains("2 of 10 cells missing") && err.contains("2 of shard 1/3 (not finished"),
        "{err}"
    );

    // The same shard command again, with --resume: it keeps its finished cell.
    let out = shard(1, &["--resume"]).output().unwrap();
    ok(&out);
    let log = String::from_utf8_lossy(&out.stderr);
    assert_eq!(log.matches("done earlier, reused").count(), 1, "{log}");
    ok(&merge());
    same_tables_as_one_process(&merged);
}

#[test]
fn merging_shards_of_different_sweeps_is_refused_in_one_line() {
    let (a, b, c) = (
        scratch("sweep-mismatch-a"),
        scratch("sweep-mismatch-b"),
        scratch("sweep-mismatch-c"),
    );
    ok(&tiny_sweep(&a, &["--shard", "0/2"]));
    // `--param` changes the scene the sweep runs (its hash), `--frames` every cell's settings.
    ok(&tiny_sweep(
        &b,
        &["--shard", "1/2", "--param", "osm_interp=cubic"],
    ));
    ok(&tiny_sweep_frames(&c, "3", &["--shard", "1/2"]));
    let merged = scratch("sweep-mismatch-merged");
    let merge = |dirs: &[&Path]| {
        let mut args = vec!["sweep", "--merge"];
        args.extend(dirs.iter().map(|d| d.to_str().unwrap()));
        args.extend(["-o", merged.to_str().unwrap()]);
        smokeshadow(&args).output().unwrap()
    };
    let one_line = |out: &Output| {
        assert_eq!(out.status.code(), Some(2));
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        err
    };
    let err = one_line(&merge(&[&a, &b]));
    assert!(
        err.contains("refused") && err.contains("scene thesis_plume has hash"),
        "{err}"
    );
    let err = one_line(&merge(&[&a, &c]));
    assert!(
        err.contains("refused") && err.contains("frames=2 against frames=3"),
        "{err}"
    );
    // Alone, shard 0 of 2 is missing shard 1's cells.
    let err = one_line(&merge(&[&a]));
    assert!(
        err.contains("missing") && err.contains("shard 1/2 (no manifest"),
        "{err}"
    );
    assert!(!merged.join("results.csv").exists());
}

/// The fenced block after `<!-- recipe: NAME -->` in docs/sweeps.md (the sharded sweeps' recipes).
fn doc_recipe(name: &str) -> String {
    let doc = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/sweeps.md"))
        .unwrap();
    let marker = format!("<!-- recipe: {name} -->");
    let after = &doc[doc.find(&marker).unwrap_or_else(|| panic!("no {marker}"))..];
    let start = after.find("```").unwrap();
    let body = &after[start..];
    let body = &body[body.find('\n').unwrap() + 1..];
    body[..body.find("```").unwrap()].to_owned()
}

/// A folder with `smokeshadow` (this build) on it, for the documented recipes (docs/sweeps.md).
fn recipe_env(root: &Path) -> String {
    let bin = root.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    std::os::unix::fs::symlink(env!("CARGO_BIN_EXE_smokeshadow"), bin.join("smokeshadow")).unwrap();
    format!("{}:{}", bin.display(), std::env::var("PATH").unwrap())
}

/// Runs a recipe's shell block in `cwd` with the two-scene settings as `SWEEP_ARGS`.
fn run_recipe(cwd: &Path, path: &str, script: &str) {
    let out = Command::new("bash")
        .args(["-euo", "pipefail", "-c", script])
        .current_dir(cwd)
        .env("PATH", path)
        .env("SWEEP_ARGS", two_scene_args().join(" "))
        .env("SMOKESHADOW_ADAPTER", "cpu")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{script}\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// docs/sweeps.md's Slurm recipe, literally: the array script, and the submission that runs it and
/// then the merge. There is no Slurm here: a stand-in `sbatch` runs the script once per index
/// of its `#SBATCH --array` with `SLURM_ARRAY_TASK_ID` set, and `--wrap` commands as they are.
#[test]
fn documented_slurm_recipe_runs_and_merges_to_the_one_process_tables() {
    let root = scratch("sweep-recipe-slurm");
    std::fs::create_dir_all(&root).unwrap();
    let path = recipe_env(&root);
    std::fs::write(
        root.join("bin/sbatch"),
        r#"#!/bin/bash
# Stand-in for Slurm's sbatch: runs an array job's tasks one after the other, or a --wrap.
set -euo pipefail
wrap=""; script=""
while [ $# -gt 0 ]; do
  case "$1" in
    --wrap) wrap="$2"; shift 2 ;;
    --wrap=*) wrap="${1#--wrap=}"; shift ;;
    --*) shift ;;
    *) script="$1"; shift ;;
  esac
done
if [ -n "$wrap" ]; then bash -c "$wrap" >&2; echo 2; exit 0; fi
range=$(sed -n 's/^#SBATCH --array=\([0-9]*-[0-9]*\).*/\1/p' "$script")
for i in $(seq "${range%-*}" "${range#*-}"); do SLURM_ARRAY_TASK_ID=$i bash "$script" >&2; done
echo 1
"#,
    )
    .unwrap();
    std::fs::set_permissions(
        root.join("bin/sbatch"),
        std::os::unix::fs::PermissionsExt::from_mode(0o755),
    )
    .unwrap();
    std::fs::write(root.join("sweep-shard.sbatch"), doc_recipe("slurm-script")).unwrap();
    run_recipe(&root, &path, &doc_recipe("slurm-submit"));
    same_tables_as_one_process(&root.join("shared/sweep"));
}

/// docs/sweeps.md's GNU parallel recipe, literally. It needs GNU parallel, which the README's
/// set-up does not install, so a plain `cargo test` skips it: `.ci/run` installs parallel and
/// runs it with `--ignored`.
#[test]
#[ignore = "needs GNU parallel (apt-get install parallel); .ci/run runs it"]
fn documented_gnu_parallel_recipe_runs_and_merges_to_the_one_process_tables() {
    let root = scratch("sweep-recipe-parallel");
    std::fs::create_dir_all(&root).unwrap();
    let path = recipe_env(&root);
    let version = Command::new("parallel").arg("--version").output();
    assert!(
        version.is_ok_and(|v| String::from_utf8_lossy(&v.stdout).contains("GNU parallel")),
        "GNU parallel is not installed (apt-get install parallel)"
    );
    run_recipe(&root, &path, &doc_recipe("parallel"));
    same_tables_as_one_process(&root.join("sweep"));
}

/// A sweep whose answer is known, checked against numbers computed here apart from the sweep:
/// `dsm` at 24 channels keeps 12 nodes per texel, enough for every texel of the plume within
/// its tolerance, so it is the closest to `exact`; `dsm` at 6 (3 nodes) is larger than `osm`
/// at 24 (17 MB of capture and nodes against 3 MB) and far less accurate, so it is off the
/// Pareto front, while the smallest cell, `osm` at 6, is on it. And every cell's RMS T column
/// equals the RMS error of the technique's own probe against `exact`'s at the frame's shaded
/// points, measured in this process by another renderer.
#[test]
fn a_sweep_with_a_known_answer_gives_it_and_its_errors_match_an_independent_probe() {
    use smokeshadow::render::shaded::{point_owners, rms_difference, shaded_points};
    use smokeshadow::render::{OUTPUT_FORMAT, Renderer, TechniqueConfig};

    let dir = scratch("sweep-known");
    let out = smokeshadow(&[
        "sweep",
        "--size",
        "160x120",
        "--techniques",
        "osm,dsm",
        "--channels",
        "24,6",
        "--bytes-per-texel",
        "none",
        "--shadow-res",
        "256",
        "--frames",
        "1",
        "--warmup",
        "0",
        "-o",
        dir.to_str().unwrap(),
    ])
    .output()
    .unwrap();
    ok(&out);
    let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
    assert!(
        html.contains("Closest to <code>exact</code> overall: <b>dsm at 24 channels</b>"),
        "the answer is not dsm at 24 channels"
    );
    let front = html
        .split("most accuracy for the memory")
        .nth(1)
        .and_then(|s| s.split(" Closest to").next())
        .unwrap()
        .to_owned();
    for on in [
        "osm at 6 channels",
        "osm at 24 channels",
        "dsm at 24 channels",
    ] {
        assert!(
            front.contains(&format!("<b>{on}</b>")),
            "{on} is not on the front: {front}"
        );
    }
    assert!(
        !front.contains("<b>dsm at 6 channels</b>"),
        "dsm at 6 is on the front: {front}"
    );

    // The RMS T column against an independent probe.
    let mut scene = smokeshadow::scene::Scene::thesis_plume();
    scene.output.width_px = 160;
    scene.output.height_px = 120;
    scene.shadow.resolution_px = 256;
    let particles = smokeshadow::particles::scene_particles(&scene).unwrap();
    let points = shaded_points(
        &scene,
        &particles,
        (160, 120),
        smokeshadow::sweep::SHADED_STRIDE_PX,
        None,
    );
    let owners = point_owners(particles.len(), points.len());
    let gpu = smokeshadow::gpu::Gpu::new(&smokeshadow::gpu::AdapterPreference::Cpu)
        .wait()
        .unwrap();
    let config = |name: &str, channels: u32| TechniqueConfig {
        name: name.to_owned(),
        params: scene.shadow.params(channels),
    };
    let mut renderer = Renderer::new(&gpu, 160, 120, OUTPUT_FORMAT, &config("exact", 1))
        .wait()
        .unwrap();
    let mut probe = |c: &TechniqueConfig| {
        renderer.set_technique(&gpu, c).wait().unwrap();
        renderer
            .probe_shaded(&gpu, &scene, &particles, &points, &owners)
            .wait()
            .unwrap()
    };
    let exact = probe(&config("exact", 1));
    let rows = csv_rows(&dir.join("results.csv"));
    let mut checked = 0;
    for row in &rows {
        let technique = get(row, "technique");
        if technique == "none" {
            continue;
        }
        let channels: u32 = get(row, "channels").parse().unwrap();
        let column: f64 = get(row, "rms_transmittance_error").parse().unwrap();
        let own = rms_difference(&probe(&config(technique, channels)), &exact);
        // (The CSV writes six decimals.)
        assert!(
            (column - own).abs() <= 5e-7 + 1e-6 * own,
            "{technique} at {channels}: the sweep says RMS T {column}, the probe here {own}"
        );
        checked += 1;
    }
    assert_eq!(checked, 4);
}

#[test]
fn byte_budgets_fit_each_technique_by_its_channel_widths_and_the_answer_ranks_at_equal_bytes() {
    let dir = scratch("sweep-bytes");
    let out = smokeshadow(&[
        "sweep",
        "--size",
        "160x120",
        "--techniques",
        "osm,fom,msm",
        "--channels",
        "24",
        "--bytes-per-texel",
        "48,16",
        "--shadow-res",
        "128",
        "--frames",
        "1",
        "--warmup",
        "0",
        "-o",
        dir.to_str().unwrap(),
    ])
    .output()
    .unwrap();
    ok(&out);
    let texels = 128u64 * 128;
    let uniform = smokeshadow::shadow::layered::PARAMS_BYTES;
    let rows = csv_rows(&dir.join("results.csv"));
    let answering = |technique: &str, budget: u32| {
        rows.iter()
            .find(|r| {
                get(r, "technique") == technique
                    && get(r, "byte_budgets")
                        .split(';')
                        .any(|b| b == budget.to_string())
            })
            .map(|r| {
                (
                    get(r, "channels_used").parse::<u64>().unwrap(),
                    get(r, "resident_bytes").parse::<u64>().unwrap(),
                )
            })
    };
    // Written out from the channel widths: osm's slices are half floats (2 bytes); fom's 2n + 1
    // coefficients and msm's b0 and moments single floats (4), the last target R, RG or RGBA.
    // Every byte is counted, the uniform's too, so a configuration of exactly the budget's
    // texels' worth does not fit: 48 bytes buy osm 22 slices (23 and 24 take 48 bytes, 23's
    // last three in an RGBA target); fom 9 coefficients (8 + 1 in an R target; 11 take 48);
    // msm its most, 9 channels (36 bytes: 8 moments and b0).
    assert_eq!(answering("osm", 48), Some((22, texels * 44 + uniform)));
    assert_eq!(answering("fom", 48), Some((9, texels * 36 + uniform)));
    assert_eq!(answering("msm", 48), Some((9, texels * 36 + uniform)));
    // 16 bytes: 6 slices (7 and 8 take 16 bytes); fom none (3 coefficients: an RGBA target, 16
    // bytes, and its uniform); msm none (5 channels: 20 bytes).
    assert_eq!(answering("osm", 16), Some((6, texels * 12 + uniform)));
    assert_eq!(answering("fom", 16), None);
    assert_eq!(answering("msm", 16), None);
    // Each cell answering a budget holds at most the budget's bytes, scratch included.
    for r in &rows {
        for budget in get(r, "byte_budgets").split(';').filter(|b| !b.is_empty()) {
            let resident: u64 = get(r, "resident_bytes").parse().unwrap();
            assert!(resident <= texels * budget.parse::<u64>().unwrap(), "{r:?}");
        }
    }
    let results: SweepResults =
        serde_json::from_str(&std::fs::read_to_string(dir.join("results.json")).unwrap()).unwrap();
    let skip = results
        .skipped
        .iter()
        .find(|s| s.technique == "msm" && s.bytes_per_texel == Some(16))
        .expect("msm at 16 bytes is skipped");
    assert!(
        skip.reason.contains("20.0 bytes a texel") && skip.reason.contains("more than 16"),
        "{}",
        skip.reason
    );
    let skip = results
        .skipped
        .iter()
        .find(|s| s.technique == "fom" && s.bytes_per_texel == Some(16))
        .expect("fom at 16 bytes is skipped");
    assert!(
        skip.reason
            .contains(&format!("{} bytes at 128²", texels * 16 + uniform)),
        "{}",
        skip.reason
    );
    // The 24-channel cells are the channel view's; the cells only a byte budget asked for are
    // off it (osm at 22 and 6, fom at 9); msm's 24-channel cell answers 48 bytes too.
    let off_axis: Vec<(&str, u32)> = results
        .cells
        .iter()
        .filter(|c| !c.channel_axis)
        .map(|c| (c.technique.as_str(), c.channels))
        .collect();
    assert_eq!(off_axis, [("osm", 22), ("osm", 6), ("fom", 9)]);

    // The answer at each budget ranks its cells by FLIP against exact, as the CSV has them; the
    // page and stdout give that order.
    let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    for budget in [48u32, 16] {
        let mut at: Vec<(f64, &str, &str)> = rows
            .iter()
            .filter(|r| {
                get(r, "byte_budgets")
                    .split(';')
                    .any(|b| b == budget.to_string())
            })
            .map(|r| {
                (
                    get(r, "flip_vs_exact").parse::<f64>().unwrap(),
                    get(r, "technique"),
                    get(r, "channels"),
                )
            })
            .collect();
        at.sort_by(|a, b| a.0.total_cmp(&b.0));
        let listed = at
            .iter()
            .map(|(flip, t, c)| format!("{t} {c} ({flip:.4})"))
            .collect::<Vec<_>>()
            .join(", ");
        assert!(
            stdout.contains(&format!(
                "at {budget} bytes a texel, by FLIP vs exact: {listed}"
            )),
            "{stdout}"
        );
        let row = &html[html.find(&format!("<tr><td>{budget} bytes</td>")).unwrap()..];
        let row = &row[..row.find("</tr>").unwrap()];
        let positions: Vec<usize> = at
            .iter()
            .map(|(_, t, c)| row.find(&format!("{t} at {c} channels (")).unwrap())
            .collect();
        assert!(positions.is_sorted(), "{row}");
    }
    // The answer at equal time: per technique its most accurate cell whose frame is within the
    // multiple of none's, ranked by FLIP, as results.json has them.
    for ratio in [1.5f64, 2.0, 4.0] {
        let mut best: Vec<(f64, &str, u32, f64)> = Vec::new();
        for c in results.cells.iter().filter(|c| c.technique != "none") {
            let overhead = c.overhead_ratio.unwrap();
            let flip = c.vs_exact.unwrap().flip_mean;
            if overhead > ratio {
                continue;
            }
            let cell = (flip, c.technique.as_str(), c.channels, overhead);
            match best.iter_mut().find(|b| b.1 == cell.1) {
                Some(b) if flip < b.0 => *b = cell,
                Some(_) => {}
                None => best.push(cell),
            }
        }
        best.sort_by(|a, b| a.0.total_cmp(&b.0));
        let listed = best
            .iter()
            .map(|(flip, t, c, o)| format!("{t} {c} ({flip:.4}, {o:.2}x)"))
            .collect::<Vec<_>>()
            .join(", ");
        let line = stdout
            .lines()
            .find(|l| l.starts_with(&format!("within {ratio:.1}x none's frame time on ")))
            .unwrap_or_else(|| panic!("no time line at {ratio}x: {stdout}"));
        match best.is_empty() {
            true => assert!(line.ends_with("no technique is that fast"), "{line}"),
            false => assert!(
                line.ends_with(&format!("by FLIP vs exact: {listed}")),
                "{line} / {listed}"
            ),
        }
    }
    assert!(html.contains("At equal time") && html.contains("Pareto front of time"));
    // What a budget cannot buy is said once: msm's 9 channels.
    assert!(
        html.contains("<code>msm</code> holds at most 36.0 bytes a texel"),
        "{html}"
    );
}
