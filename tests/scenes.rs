//! Scene files: the committed scenes load, and bad files are rejected with a message that names
//! the problem (field, value, range; or line and column).

use smokeshadow::scene::{Scene, SceneError, THESIS_PLUME_TOML};

#[test]
fn committed_scenes_load_and_match_the_thesis_setup() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut count = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            Scene::load(&path, &smokeshadow::files::Files::host())
                .unwrap_or_else(|e| panic!("{e}"));
            count += 1;
        }
    }
    assert!(count >= 2);
    // Thesis chapter 4: 2500 particles, 1024x768 screen, 512x512 shadow map.
    let plume = Scene::thesis_plume();
    assert_eq!(plume.emitters[0].count, 2500);
    assert_eq!((plume.output.width_px, plume.output.height_px), (1024, 768));
    assert_eq!(plume.shadow.resolution_px, 512);
    assert!(!plume.boxes.is_empty());
    // The wind scene is the same experiment with a gust.
    let wind = Scene::load(
        &dir.join("thesis_wind.toml"),
        &smokeshadow::files::Files::host(),
    )
    .unwrap();
    assert!(wind.wind.strength_m_per_s > 0.0 && wind.wind.start_s < wind.sim.duration_s);
    assert_eq!(wind.emitters, plume.emitters);
    assert_eq!(wind.camera, plume.camera);
    assert_eq!(wind.light, plume.light);
}

#[test]
fn scenes_round_trip_through_toml() {
    let plume = Scene::thesis_plume();
    let again = Scene::from_toml_str(&plume.to_toml(), "round trip").unwrap();
    assert_eq!(plume, again);
}

/// Replaces `from` (which must occur) in the thesis scene.
fn edited(from: &str, to: &str) -> String {
    assert!(THESIS_PLUME_TOML.contains(from), "{from}");
    THESIS_PLUME_TOML.replacen(from, to, 1)
}

#[test]
fn bad_scenes_are_rejected_with_a_clear_message() {
    let line_of = |needle: &str| {
        let n = THESIS_PLUME_TOML
            .lines()
            .position(|l| l.starts_with(needle))
            .unwrap()
            + 1;
        format!("line {n}")
    };
    let camera_next = format!(
        "line {}",
        THESIS_PLUME_TOML
            .lines()
            .position(|l| l == "[camera]")
            .unwrap()
            + 2
    );
    let width_line = line_of("width_px");
    let output_line = line_of("[output]");
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            edited("count = 2500", "count = 0"),
            vec!["emitter.count = 0", "1..=4000000"],
        ),
        (
            edited("count = 2500", "count = 4000001"),
            vec!["emitter.count = 4000001", "1..=4000000"],
        ),
        (
            edited("width_px = 1024", "width_px = 0"),
            vec!["output.width_px = 0", "1..=8192"],
        ),
        (
            edited("height_px = 768", "height_px = 9000"),
            vec!["output.height_px = 9000", "1..=8192"],
        ),
        (
            edited("density_per_m = 2.4", "density_per_m = -1.0"),
            vec!["emitter.density_per_m = -1", ">= 0"],
        ),
        (
            edited("resolution_px = 512", "resolution_px = 0"),
            vec!["shadow.resolution_px = 0", "1..=8192"],
        ),
        (
            edited("resolution_px = 512", "resolution_px = 512\nhistory = 1.0"),
            vec!["shadow.history = 1", "[0, 0.99]"],
        ),
        (
            edited("cone_angle_deg = 34.0", "cone_angle_deg = 95.0"),
            vec!["light.cone_angle_deg = 95", "(0, 80)"],
        ),
        (
            edited("hg_g = 0.35", "hg_g = 1.0"),
            vec!["shading.hg_g = 1", "(-1, 1)"],
        ),
        (
            edited("step_s = 0.016666668", "step_s = 0.0"),
            vec!["sim.step_s = 0"],
        ),
        (
            edited("[camera]\n", "[camera]\nzoom = 2.0\n"),
            vec!["unknown field `zoom`", &camera_next],
        ),
        (
            edited("width_px = 1024", "width_px = \"wide\""),
            vec![&width_line, "column 12"],
        ),
        (edited("[output]", "[output"), vec![&output_line]),
        (
            edited("target = [0.4, 2.5, 0.0]", "target = [0.0, 2.7, 11.5]"),
            vec!["camera.position and camera.target must differ"],
        ),
    ];
    for (text, expected) in cases {
        let err = Scene::from_toml_str(&text, "bad.toml").expect_err("should be rejected");
        let msg = err.to_string();
        assert!(!msg.contains('\n'), "one line: {msg}");
        assert!(msg.starts_with("bad.toml"), "names the file: {msg}");
        for needle in expected {
            assert!(msg.contains(needle), "`{msg}` lacks `{needle}`");
        }
    }
}

#[test]
fn a_missing_file_names_its_path() {
    let err = Scene::load(
        std::path::Path::new("/no/such/scene.toml"),
        &smokeshadow::files::Files::host(),
    )
    .unwrap_err();
    assert!(matches!(err, SceneError::Read { .. }));
    assert!(err.to_string().contains("/no/such/scene.toml"));
}

#[test]
fn the_scaling_family_is_the_thesis_plume_at_other_counts() {
    let thesis = Scene::thesis_plume();
    let base = Scene::embedded("plume_scaled").unwrap();
    assert_eq!(base.name, "plume_scaled");
    assert_eq!(
        Scene {
            name: thesis.name.clone(),
            description: thesis.description.clone(),
            ..base.clone()
        },
        thesis,
        "plume_scaled is thesis_plume under another name"
    );
    // plume_65k is the rule applied at 65,536, to the bit (the file's decimals round-trip).
    let k65 = Scene::embedded("plume_65k").unwrap();
    let scaled = base.clone().with_particles(65_536).unwrap();
    assert_eq!(k65.emitters, scaled.emitters);
    assert_eq!(
        Scene {
            name: base.name.clone(),
            description: base.description.clone(),
            ..k65.clone()
        },
        scaled
    );
    // The rule: radii times (N0/N)^(1/3), τ kept; the same count changes nothing.
    let e = &scaled.emitters[0];
    let k = (2500.0f64 / 65536.0).cbrt();
    assert!(
        (f64::from(e.radius_birth_m) / f64::from(base.emitters[0].radius_birth_m) - k).abs() < 1e-6
    );
    assert!(
        (f64::from(e.growth_m_per_s) / f64::from(base.emitters[0].growth_m_per_s) - k).abs() < 1e-6
    );
    assert_eq!(e.density_per_m, base.emitters[0].density_per_m);
    assert_eq!(base.clone().with_particles(2500).unwrap(), base);
    // Embedded ones are listed; only the thesis scenes have baselines.
    for name in ["plume_scaled", "plume_65k"] {
        assert!(smokeshadow::scene::embedded_names().contains(name));
        assert!(!smokeshadow::scene::BASELINE_SCENES.contains(&name));
    }
}

#[test]
fn a_count_beyond_the_limit_is_refused_with_the_field_and_range() {
    let err = Scene::thesis_plume()
        .with_particles(4_000_001)
        .unwrap_err()
        .to_string();
    assert!(err.contains("emitter.count = 4000001"), "{err}");
    assert!(err.contains("1..=4000000"), "{err}");
    assert!(!err.contains('\n'), "{err}");
}

#[test]
fn more_boxes_than_a_scene_may_hold_are_refused_in_one_line() {
    // The exact occluder test loops over every box: llvmpipe's loop budget holds 1,024.
    let limit = smokeshadow::frame::occluders::MAX_BOXES;
    let mut scene = Scene::thesis_plume();
    let the_box = scene.boxes[0].clone();
    scene.boxes = vec![the_box; limit];
    Scene::from_toml_str(&scene.to_toml(), "many.toml").unwrap();
    scene.boxes.push(scene.boxes[0].clone());
    let err = Scene::from_toml_str(&scene.to_toml(), "many.toml")
        .expect_err("too many boxes")
        .to_string();
    assert!(err.contains("1025 boxes"), "{err}");
    assert!(err.contains("1024"), "{err}");
    assert!(!err.contains('\n'), "{err}");
}

#[test]
fn technique_parameters_take_numbers_and_the_names_of_choices() {
    use smokeshadow::scene::ParamValue;
    use smokeshadow::shadow::{check_params, find_param};
    let text = format!(
        "{THESIS_PLUME_TOML}\n[shadow.params]\nosm_interp = \"cubic\"\ndom_interp = 1\n\
         dom_layer_growth = 2\n"
    );
    let scene = Scene::from_toml_str(&text, "choices.toml").unwrap();
    let params = scene.shadow.params(8);
    check_params(&params).unwrap();
    let value = |key| params.get(find_param(key).unwrap());
    assert_eq!(value("osm_interp"), Some(1.0));
    assert_eq!(value("dom_interp"), Some(1.0));
    assert_eq!(value("dom_layer_growth"), Some(2.0));
    assert_eq!(
        scene.shadow.params["osm_interp"],
        ParamValue::Choice("cubic".to_owned())
    );
    // A name is written back as a name.
    let toml = scene.to_toml();
    assert!(toml.contains("osm_interp = \"cubic\""), "{toml}");
    assert_eq!(Scene::from_toml_str(&toml, "again").unwrap(), scene);

    // The scene names what it does not know the registry's way: a wrong name is refused when a
    // technique is made from it, naming the choices; a value of another type at load.
    let bad = format!("{THESIS_PLUME_TOML}\n[shadow.params]\nosm_interp = \"spline\"\n");
    let scene = Scene::from_toml_str(&bad, "bad.toml").unwrap();
    let err = check_params(&scene.shadow.params(8))
        .unwrap_err()
        .to_string();
    assert_eq!(
        err,
        "parameter osm_interp = \"spline\" is not one of its choices: linear, cubic"
    );
    let bad = format!("{THESIS_PLUME_TOML}\n[shadow.params]\nosm_interp = true\n");
    let err = Scene::from_toml_str(&bad, "bad.toml")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("a number, or the name of one of the parameter's choices"),
        "{err}"
    );
}

/// The thesis scene with its `[emitter]` table written as `[[emitters]]` tables: `extra` is
/// appended after the first (more `[[emitters]]` entries).
fn as_emitters_array(extra: &str) -> String {
    let text = THESIS_PLUME_TOML.replace("[emitter]", "[[emitters]]");
    let at = text
        .find("[wind]")
        .expect("the thesis scene has a [wind] table");
    format!("{}{extra}\n{}", &text[..at], &text[at..])
}

fn bits(particles: &[smokeshadow::sim::Particle]) -> Vec<u32> {
    particles
        .iter()
        .flat_map(|p| {
            let (q, v, a) = (p.position, p.velocity, p.albedo);
            [
                q.x,
                q.y,
                q.z,
                v.x,
                v.y,
                v.z,
                p.age_s,
                p.radius_m,
                p.density_per_m,
                a.x,
                a.y,
                a.z,
            ]
        })
        .map(f32::to_bits)
        .collect()
}

#[test]
fn one_emitter_table_and_a_one_entry_emitters_array_are_the_same_scene() {
    let table = Scene::thesis_plume();
    let array = Scene::from_toml_str(&as_emitters_array(""), "array").unwrap();
    assert_eq!(array, table);
    // Written back, a one-emitter scene keeps the `[emitter]` form, so its canonical text (and
    // the hash the baselines record) did not change with `[[emitters]]`.
    assert!(table.to_toml().contains("\n[emitter]\n"));
    assert!(!table.to_toml().contains("[[emitters]]"));
    assert_eq!(array.content_hash(), table.content_hash());
}

#[test]
fn each_emitter_makes_exactly_the_particles_it_would_make_alone() {
    let second = "[[emitters]]\ncount = 400\nseed = 7\nposition = [2.5, 0.5, -1.0]\n\
                  velocity_m_per_s = [0.0, 0.2, 0.0]\nlifetime_s = 3.0\nturbulence_m_per_s2 = 1.5\n";
    let both = Scene::from_toml_str(&as_emitters_array(second), "two").unwrap();
    assert_eq!(both.emitters.len(), 2);
    assert_eq!(both.particle_count(), 2900);
    let mut first_alone = both.clone();
    first_alone.emitters.truncate(1);
    let mut second_alone = both.clone();
    second_alone.emitters.remove(0);

    let all = smokeshadow::sim::simulate(&both);
    let a = smokeshadow::sim::simulate(&first_alone);
    let b = smokeshadow::sim::simulate(&second_alone);
    assert_eq!(all.len(), 2900, "both pools are full after a lifetime");
    assert_eq!(
        bits(&all[..a.len()]),
        bits(&a),
        "the first emitter's particles"
    );
    assert_eq!(
        bits(&all[a.len()..]),
        bits(&b),
        "the second emitter's particles"
    );
    // And the first is the thesis plume, bit for bit.
    assert_eq!(
        bits(&a),
        bits(&smokeshadow::sim::simulate(&Scene::thesis_plume()))
    );
    // The second emitter's particles are its own: born at its source, within its lifetime.
    assert!(b.iter().all(|p| p.age_s < 3.0));
    let mean_x = b.iter().map(|p| p.position.x).sum::<f32>() / b.len() as f32;
    assert!(
        (mean_x - 2.5).abs() < 1.0,
        "second plume centred at x = {mean_x}"
    );

    // Several emitters round-trip through TOML as `[[emitters]]`.
    let text = both.to_toml();
    assert!(text.contains("[[emitters]]") && !text.contains("\n[emitter]\n"));
    assert_eq!(Scene::from_toml_str(&text, "written").unwrap(), both);
}

#[test]
fn bad_emitters_are_named_by_their_index() {
    let both = as_emitters_array("[[emitters]]\ncount = 0\nlifetime_s = -1.0\n");
    let err = Scene::from_toml_str(&both, "s.toml")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("emitters[1].count = 0 is out of range"),
        "{err}"
    );
    assert!(err.contains("emitters[1].lifetime_s = -1"), "{err}");
    assert!(!err.contains('\n'), "one line: {err}");

    let table_and_array = format!("{THESIS_PLUME_TOML}\n[[emitters]]\ncount = 10\n");
    let err = Scene::from_toml_str(&table_and_array, "s.toml")
        .unwrap_err()
        .to_string();
    assert!(err.starts_with("s.toml: "), "{err}");
    assert!(err.contains("both [emitter] and [[emitters]]"), "{err}");
    assert!(!err.contains('\n'), "one line: {err}");

    let too_many = as_emitters_array("[[emitters]]\ncount = 3999000\n");
    let err = Scene::from_toml_str(&too_many, "s.toml")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("4001500 particles in all is too many"),
        "{err}"
    );
}

#[test]
fn scaling_several_emitters_keeps_their_shares_and_the_total() {
    let second = "[[emitters]]\ncount = 500\nseed = 3\nposition = [3.0, 0.0, 0.0]\n";
    let both = Scene::from_toml_str(&as_emitters_array(second), "two").unwrap();
    let scaled = both.clone().with_particles(30_001).unwrap();
    assert_eq!(scaled.particle_count(), 30_001);
    assert_eq!(
        scaled.emitters[0].count, 25_000,
        "2500 of 3000 -> 25000 of 30001"
    );
    assert_eq!(scaled.emitters[1].count, 5_001);
    for (s, e) in scaled.emitters.iter().zip(&both.emitters) {
        let k = (f64::from(e.count) / f64::from(s.count)).cbrt();
        let ratio = f64::from(s.radius_birth_m) / f64::from(e.radius_birth_m);
        assert!(
            (ratio - k).abs() < 1e-6,
            "radius scaled by {ratio}, expected {k}"
        );
        assert_eq!(s.density_per_m, e.density_per_m);
    }
}

#[test]
fn a_scene_says_what_it_is_from_its_description_or_its_embedded_header() {
    let thesis = Scene::thesis_plume();
    assert!(
        thesis.description.is_empty(),
        "the baselines' hash needs it empty"
    );
    assert!(
        thesis.summary().starts_with("The thesis experiment"),
        "{}",
        thesis.summary()
    );
    // Another output size is still the thesis smoke; another emitter is not.
    let mut resized = thesis.clone();
    resized.output.width_px = 160;
    assert_eq!(resized.summary(), thesis.summary());
    let mut other = thesis.clone();
    other.emitters[0].seed += 1;
    assert_eq!(other.summary(), "");
    other.description = "My smoke.".into();
    assert_eq!(other.summary(), "My smoke.");
}
