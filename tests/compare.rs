//! `smokeshadow compare` on a reduced scene writes every file it lists, a CSV with a row per
//! compared pair, and an HTML page that references only files that exist.

use std::path::Path;
use std::process::Command;

#[test]
fn compare_writes_every_listed_file_and_a_page_without_dangling_links() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("compare");
    let _ = std::fs::remove_dir_all(&dir);
    let result = Command::new(env!("CARGO_BIN_EXE_smokeshadow"))
        .args([
            "compare",
            "thesis_wind",
            "--size",
            "160x120",
            "--techniques",
            "osm,dom,fom",
            "--channels",
            "8,6,4",
            "-o",
            dir.to_str().unwrap(),
        ])
        .env("SMOKESHADOW_ADAPTER", "cpu")
        .output()
        .unwrap();
    assert!(
        result.status.success(),
        "{}",
        String::from_utf8_lossy(&result.stderr)
    );

    let techniques = ["osm", "dom", "fom"];
    let budgets = [8, 6, 4];
    let mut expected = vec![
        "images/exact.png".to_owned(),
        "metrics.csv".into(),
        "index.html".into(),
    ];
    for t in techniques {
        for (i, b) in budgets.iter().enumerate() {
            expected.push(format!("images/{t}_{b}.png"));
            expected.push(format!("diffs/{t}_{b}_vs_exact_x4.png"));
            expected.push(format!("diffs/{t}_{b}_vs_exact_flip.png"));
            if i > 0 {
                expected.push(format!("diffs/{t}_{b}_vs_{t}_8_x4.png"));
                expected.push(format!("diffs/{t}_{b}_vs_{t}_8_flip.png"));
            }
        }
    }
    for (a, b) in [("osm", "dom"), ("osm", "fom"), ("dom", "fom")] {
        expected.push(format!("diffs/{a}_8_vs_{b}_8_x4.png"));
        expected.push(format!("diffs/{a}_8_vs_{b}_8_flip.png"));
    }
    for file in &expected {
        assert!(dir.join(file).is_file(), "{file} was not written");
    }
    let image = image::open(dir.join("images/osm_6.png")).unwrap();
    assert_eq!((image.width(), image.height()), (160, 120));

    // One CSV row per pair: every image against exact, the lower budgets against their own
    // baseline, and the baseline pairs.
    let csv = std::fs::read_to_string(dir.join("metrics.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert!(rows[0].starts_with("test,reference,kind,"), "{}", rows[0]);
    assert_eq!(rows.len() - 1, 9 + 6 + 3, "{csv}");
    for row in &rows[1..] {
        let flip: f64 = row.split(',').nth(7).unwrap().parse().unwrap();
        assert!((0.0..=1.0).contains(&flip), "{row}");
    }

    let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
    let links = smokeshadow::compare::referenced_paths(&html);
    assert!(links.len() > expected.len(), "{} links", links.len());
    for link in links {
        assert!(
            !link.is_absolute() && !link.to_string_lossy().contains("://"),
            "{link:?}"
        );
        assert!(
            dir.join(&link).is_file(),
            "index.html links to missing {link:?}"
        );
    }
    assert!(html.contains("Most accurate per budget"));
}
