//! The committed 24-channel baselines against fresh renders on lavapipe (the same check as
//! `smokeshadow baseline --check`), and the check's failure modes. Thresholds per technique are
//! in `smokeshadow::baseline::flip_threshold`, with what they guard against.

mod common;

use std::path::Path;
use std::process::Command;

use common::scratch;
use smokeshadow::baseline;

#[test]
fn committed_baselines_match_fresh_renders() {
    let gpu = common::gpu();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("baselines");
    let out = Path::new(env!("CARGO_MANIFEST_DIR")).join("test-output/baselines");
    let selected = baseline::select(&dir, &[], &[]).unwrap();
    // Every registered technique on both thesis scenes.
    assert_eq!(
        selected.len(),
        2 * smokeshadow::shadow::REGISTRY.len(),
        "{selected:?}"
    );
    let rows = baseline::check(&gpu, &selected, &out).unwrap();
    let failures: Vec<String> = rows
        .iter()
        .filter_map(|r| {
            r.failure
                .as_ref()
                .map(|why| format!("{}/{}: {why}", r.baseline.scene, r.baseline.technique))
        })
        .collect();
    assert!(
        failures.is_empty(),
        "baselines failed:\n{}",
        failures.join("\n")
    );
}

/// Runs `smokeshadow baseline --check` on one baseline in `dir`.
fn check_one(dir: &Path, out: &Path) -> (i32, String) {
    let result = Command::new(env!("CARGO_BIN_EXE_smokeshadow"))
        .args([
            "baseline",
            "--check",
            "--scene",
            "thesis_plume",
            "--technique",
            "none",
            "--dir",
            dir.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .env("SMOKESHADOW_ADAPTER", "cpu")
        .output()
        .unwrap();
    (
        result.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&result.stdout).into_owned(),
    )
}

#[test]
fn missing_mis_sized_and_changed_baselines_fail_and_say_how_to_bless() {
    let committed = Path::new(env!("CARGO_MANIFEST_DIR")).join("baselines/thesis_plume");
    let dir = scratch("baseline-failures");
    let out = dir.join("out");
    let folder = dir.join("thesis_plume");
    std::fs::create_dir_all(&folder).unwrap();
    let copy = || {
        for ext in ["png", "json"] {
            std::fs::copy(
                committed.join(format!("none.{ext}")),
                folder.join(format!("none.{ext}")),
            )
            .unwrap();
        }
    };

    copy();
    let (code, text) = check_one(&dir, &out);
    assert_eq!(code, 0, "an intact copy passes:\n{text}");

    std::fs::remove_file(folder.join("none.png")).unwrap();
    let (code, text) = check_one(&dir, &out);
    assert_eq!(code, 1, "{text}");
    assert!(
        text.contains("missing baseline") && text.contains("smokeshadow baseline --bless"),
        "{text}"
    );

    copy();
    image::RgbImage::new(64, 48)
        .save(folder.join("none.png"))
        .unwrap();
    let (code, text) = check_one(&dir, &out);
    assert_eq!(code, 1, "{text}");
    assert!(
        text.contains("64x48") && text.contains("1024x768"),
        "{text}"
    );

    // A different picture of the right size fails on FLIP and leaves the evidence behind.
    copy();
    let mut image = image::open(folder.join("none.png")).unwrap().into_rgb8();
    for p in image.pixels_mut().take(200 * 1024) {
        p.0 = [255, 0, 255];
    }
    image.save(folder.join("none.png")).unwrap();
    let (code, text) = check_one(&dir, &out);
    assert_eq!(code, 1, "{text}");
    assert!(text.contains("FLIP mean"), "{text}");
    for suffix in ["actual", "diff", "flip"] {
        let path = out.join(format!("thesis_plume/none-{suffix}.png"));
        assert!(path.is_file(), "{} missing", path.display());
    }

    // A sidecar from another scene version: stale.
    copy();
    let sidecar = std::fs::read_to_string(folder.join("none.json")).unwrap();
    let stale = sidecar.replacen("\"scene_sha256\": \"", "\"scene_sha256\": \"0", 1);
    std::fs::write(folder.join("none.json"), stale).unwrap();
    let (code, text) = check_one(&dir, &out);
    assert_eq!(code, 1, "{text}");
    assert!(
        text.contains("changed since") && text.contains("--bless"),
        "{text}"
    );
}
