//! `tune`: one procedure chooses every technique's parameters on training scenes apart from the
//! thesis and gallery scenes; its file is what `--params FILE` reads, the registry's defaults are
//! its committed output, and bad parameter files get one line.

use smokeshadow::Wait;
mod common;

use common::{error_lines, scratch, smokeshadow};
use smokeshadow::render::shaded::{point_owners, rms_difference, shaded_points};
use smokeshadow::render::{OUTPUT_FORMAT, Renderer, TechniqueConfig};
use smokeshadow::scene::{BASELINE_SCENES, GALLERY, Scene, TRAINING};
use smokeshadow::shadow::{self, ParamValue};
use smokeshadow::tune::ParamsFile;

fn read(path: &std::path::Path) -> ParamsFile {
    toml::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn tune_scores_every_technique_alike_and_writes_a_file_the_other_commands_read() {
    let dir = scratch("tune");
    let file = dir.join("p.toml");
    let out = smokeshadow(&[
        "tune",
        "--techniques",
        "esm,volume",
        "--evaluations",
        "3",
        "--size",
        "128x96",
        "--bytes-per-texel",
        "24",
        "--memory",
        "768KiB",
        "--shape-res",
        "128,256",
        "-o",
        file.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{:?}", error_lines(&out));
    let stderr = String::from_utf8_lossy(&out.stderr);
    // The same number of candidates for each technique.
    for t in ["esm", "volume"] {
        let scored = stderr
            .lines()
            .filter(|l| l.starts_with(&format!("{t} ")) && l.contains("/3:"))
            .count();
        assert_eq!(scored, 3, "{t}: {stderr}");
    }
    let p = read(&file);
    let record = p.tune.expect("tune records how it chose");
    assert_eq!(record.training, TRAINING);
    assert_eq!(record.held_out, ["thesis_plume"]);
    assert_eq!((record.evaluations, record.bytes_per_texel), (3, vec![24]));
    for t in ["esm", "volume"] {
        let r = &record.techniques[t];
        // The chosen values are the best scored, the starting values among them.
        assert!(r.chosen_training <= r.start_training, "{t}: {r:?}");
        assert!(r.start_held_out.is_some() && r.chosen_held_out.is_some());
    }
    // Each technique's shape at 768 KiB: the resolution of the lowest mean error it printed.
    assert_eq!(
        (record.memory.clone(), record.shape_resolutions.clone()),
        (vec![768 << 10], vec![128, 256])
    );
    for t in ["esm", "volume"] {
        let printed: Vec<(u32, f64)> = stderr
            .lines()
            .filter_map(|l| l.strip_prefix(&format!("{t} shape at 768.0 KiB: ")))
            .filter_map(|rest| {
                let (res, score) = rest.split_once("² -> ")?;
                Some((res.parse().ok()?, score.parse().ok()?))
            })
            .collect();
        assert_eq!(printed.len(), 2, "{t}: {stderr}");
        let best = printed.iter().min_by(|a, b| a.1.total_cmp(&b.1)).unwrap();
        let shape = p.shapes[t]["786432"];
        assert_eq!(shape.resolution, best.0, "{t}: {printed:?}");
        assert!((shape.training - best.1).abs() < 1e-5, "{t}: {printed:?}");
    }
    let keys: Vec<&str> = p.params.keys().map(String::as_str).collect();
    assert_eq!(
        keys,
        ["esm_exponent_per_m", "volume_light_aligned", "volume_steps"]
    );
    match &p.params["volume_steps"] {
        ParamValue::Number(k) => assert_eq!(k.fract(), 0.0, "steps are whole"),
        other => panic!("{other:?}"),
    }

    // esm's starting score, computed here apart from tune: the mean over the training scenes of
    // the RMS of T - T_exact at the shaded points, its defaults at 24 bytes a texel.
    let gpu = smokeshadow::gpu::Gpu::new(&smokeshadow::gpu::AdapterPreference::Cpu)
        .wait()
        .unwrap();
    let mut sum = 0.0;
    for name in TRAINING {
        let mut scene = Scene::embedded(name).unwrap();
        scene.output.width_px = 128;
        scene.output.height_px = 96;
        let particles = smokeshadow::particles::scene_particles(&scene).unwrap();
        let points = shaded_points(&scene, &particles, (128, 96), 4, None);
        let owners = point_owners(particles.len(), points.len());
        let t = |name: &str, channels| {
            let config = TechniqueConfig {
                name: name.to_owned(),
                params: scene.shadow.params(channels),
            };
            let mut r = Renderer::new(&gpu, 128, 96, OUTPUT_FORMAT, &config)
                .wait()
                .unwrap();
            r.probe_shaded(&gpu, &scene, &particles, &points, &owners)
                .wait()
                .unwrap()
        };
        // esm keeps 2 bytes a texel at any budget: its smallest configuration.
        sum += rms_difference(&t("esm", 1), &t("exact", 1));
    }
    let independent = sum / TRAINING.len() as f64;
    let recorded = record.techniques["esm"].start_training;
    assert!(
        (independent - recorded).abs() < 1e-5,
        "tune recorded {recorded}, computed here {independent}"
    );

    // The file and the papers' set are what --params reads.
    for set in [file.to_str().unwrap(), "paper"] {
        let png = dir.join("r.png");
        let out = smokeshadow(&[
            "render",
            "-t",
            "msm",
            "--size",
            "48x32",
            "--particles",
            "200",
            "--params",
            set,
            "-o",
            png.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{set}: {:?}", error_lines(&out));
        assert!(png.is_file());
    }
}

#[test]
fn bad_tuning_input_and_parameter_files_get_one_line() {
    let dir = scratch("tune-bad");
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "[params]\nmsm_bias = 9.0\n").unwrap();
    let png = dir.join("x.png");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["tune", "--scenes", "thesis_plume"],
            "where the answers are given",
        ),
        (
            vec!["tune", "--scenes", "column"],
            "where the answers are given",
        ),
        (
            vec!["tune", "--scenes", "holdout_jet"],
            "held out from tuning",
        ),
        (
            vec!["tune", "--held-out", "holdout_stack"],
            "held out from tuning",
        ),
        (
            vec![
                "render",
                "--params",
                "/no/such.toml",
                "-o",
                png.to_str().unwrap(),
            ],
            "cannot read",
        ),
        (
            vec![
                "render",
                "--params",
                bad.to_str().unwrap(),
                "-o",
                png.to_str().unwrap(),
            ],
            "msm_bias = 9 is out of range",
        ),
        (vec!["tune", "--techniques", "exact"], "only contenders"),
    ];
    for (args, says) in cases {
        let out = smokeshadow(&args);
        let lines = error_lines(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert_eq!(lines.len(), 1, "{args:?}: {lines:?}");
        assert!(lines[0].contains(says), "{args:?}: {}", lines[0]);
        assert!(!png.exists());
    }
}

#[test]
fn the_shipped_defaults_are_the_committed_output_of_tune_on_training_scenes_only() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/tuned_params.toml");
    let file = read(&path);
    let record = file
        .tune
        .clone()
        .expect("the committed file records its command");
    assert!(
        record.command.starts_with("smokeshadow tune"),
        "{}",
        record.command
    );
    for scene in &record.training {
        assert!(
            TRAINING.contains(&scene.as_str())
                && !GALLERY.contains(&scene.as_str())
                && !BASELINE_SCENES.contains(&scene.as_str()),
            "{scene} is not a training scene"
        );
    }
    // Its shapes are chosen over the budgets and resolutions it records, and the sweep's
    // shipped shapes are the file's.
    assert!(!file.shapes.is_empty(), "the committed file has shapes");
    for (technique, by_memory) in &file.shapes {
        shadow::find(technique).unwrap();
        for (total, shape) in by_memory {
            assert!(
                record.memory.contains(&total.parse().unwrap()),
                "{technique} {total}"
            );
            assert!(record.shape_resolutions.contains(&shape.resolution));
        }
    }
    assert_eq!(smokeshadow::tune::shipped_shapes(), file.shapes());
    // Every tuned technique's every free parameter is in the file, at the registry's default.
    for name in record.techniques.keys() {
        let entry = shadow::find(name).unwrap();
        for spec in smokeshadow::tune::free_params(entry) {
            let value = file
                .params
                .get(spec.key)
                .unwrap_or_else(|| panic!("{} is not in the file", spec.key));
            assert_eq!(
                spec.resolve(value).unwrap(),
                spec.default.unwrap(),
                "{}: the registry's default is not tune's choice",
                spec.key
            );
        }
    }
    // And every contender with parameters was tuned.
    for entry in shadow::contenders() {
        if !smokeshadow::tune::free_params(entry).is_empty() {
            assert!(record.techniques.contains_key(entry.name), "{}", entry.name);
        }
    }
}
