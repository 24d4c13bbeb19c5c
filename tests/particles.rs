//! Particle files: export, import, the exact round trip (particles and image), the property
//! names of other tools, sequences, and every kind of bad file getting one line.

mod common;

use std::path::Path;
use std::process::Output;

use common::{error_lines, scratch, smokeshadow};
use smokeshadow::particles::{self, Defaults};
use smokeshadow::scene::Scene;
use smokeshadow::sim::{Particle, simulate};

fn ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn bits(ps: &[Particle]) -> Vec<u32> {
    ps.iter()
        .flat_map(particles::values_of)
        .map(f32::to_bits)
        .collect()
}

/// The thesis scene with `[particles] file = "<file>"` instead of its emitter.
fn scene_reading(file: &str) -> String {
    let text = smokeshadow::scene::THESIS_PLUME_TOML;
    let (a, b) = (
        text.find("[emitter]").unwrap(),
        text.find("[wind]").unwrap(),
    );
    format!(
        "{}[particles]\nfile = \"{file}\"\n\n{}",
        &text[..a],
        &text[b..]
    )
}

#[test]
fn every_format_round_trips_the_simulated_particles_bit_for_bit() {
    let dir = scratch("particles_round_trip");
    let simulated = simulate(&Scene::thesis_plume());
    for (name, format) in [
        ("p.ply", None),
        ("p_ascii.ply", Some("ply-ascii")),
        ("p.csv", None),
    ] {
        let path = dir.join(name);
        let mut args = vec!["particles", "-o", path.to_str().unwrap()];
        if let Some(f) = format {
            args.extend(["--format", f]);
        }
        let stdout = ok(&smokeshadow(&args));
        assert!(stdout.contains("2500 particles"), "{stdout}");
        let read = particles::read(
            &smokeshadow::files::Files::host(),
            &path,
            &Defaults::default(),
        )
        .unwrap();
        assert_eq!(bits(&read), bits(&simulated), "{name}");
    }
    // The ASCII PLY really is ASCII, the binary one binary.
    let ascii = std::fs::read(dir.join("p_ascii.ply")).unwrap();
    assert!(ascii.starts_with(b"ply\nformat ascii 1.0\n"));
    let binary = std::fs::read(dir.join("p.ply")).unwrap();
    assert!(binary.starts_with(b"ply\nformat binary_little_endian 1.0\n"));
    // 12 floats a particle after the header.
    let header = binary
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    assert_eq!(binary.len() - header, 2500 * 12 * 4);
}

#[test]
fn an_exported_frame_renders_the_same_image_as_the_emitter_scene() {
    let dir = scratch("particles_render_round_trip");
    ok(&smokeshadow(&[
        "particles",
        "-o",
        dir.join("plume.ply").to_str().unwrap(),
    ]));
    let scene = dir.join("from_file.toml");
    std::fs::write(&scene, scene_reading("plume.ply")).unwrap();
    let (a, b) = (dir.join("emitter.png"), dir.join("file.png"));
    for (scene, png) in [(None, &a), (Some(&scene), &b)] {
        let mut args = vec!["render", "--size", "200x150", "--technique", "fom"];
        args.extend(["--channels", "8", "-o", png.to_str().unwrap()]);
        if let Some(scene) = scene {
            args.insert(1, scene.to_str().unwrap());
        }
        let stdout = ok(&smokeshadow(&args));
        assert!(stdout.contains("2500 particles"), "{stdout}");
    }
    let load = |p: &Path| image::open(p).unwrap().into_rgb8();
    let comparison = smokeshadow::diff::compare(&load(&a), &load(&b)).unwrap();
    assert_eq!(
        comparison.metrics.flip_mean, 0.0,
        "FLIP between the two frames"
    );
    assert_eq!(load(&a), load(&b));
}

/// A PLY as someone writes it by hand with Houdini's attribute names: P as x y z, pscale,
/// density, Cd as float red green blue, and attributes we do not read (id, life, v).
fn houdini_ply(particles: &[(f32, f32, f32, f32, f32)]) -> String {
    let mut text = format!(
        "ply\nformat ascii 1.0\ncomment written by hand in Houdini's names\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property int id\nproperty float pscale\nproperty float density\n\
         property float red\nproperty float green\nproperty float blue\nproperty float life\n\
         end_header\n",
        particles.len()
    );
    for (i, (x, y, z, pscale, density)) in particles.iter().enumerate() {
        text.push_str(&format!(
            "{x} {y} {z} {i} {pscale} {density} 0.9 0.85 0.8 6\n"
        ));
    }
    text
}

#[test]
fn a_ply_in_houdinis_names_renders_smoke_where_its_particles_are() {
    let dir = scratch("particles_houdini");
    // A 5 x 5 x 5 block of puffs, 1.2 m to 3.2 m up, in Houdini's names.
    let mut puffs = Vec::new();
    for i in 0..5 {
        for j in 0..5 {
            for k in 0..5 {
                let at = |n: i32| -1.0 + 0.5 * n as f32;
                puffs.push((at(i), 1.2 + 0.5 * j as f32, at(k), 0.45, 3.0));
            }
        }
    }
    let path = dir.join("houdini.ply");
    std::fs::write(&path, houdini_ply(&puffs)).unwrap();
    let read = particles::read(
        &smokeshadow::files::Files::host(),
        &path,
        &Defaults::default(),
    )
    .unwrap();
    assert_eq!(read.len(), 125);
    assert_eq!(read[1].radius_m, 0.45, "pscale is the radius");
    assert_eq!(read[1].density_per_m, 3.0);
    assert_eq!(read[1].albedo, glam::Vec3::new(0.9, 0.85, 0.8), "Cd");
    assert_eq!(read[1].age_s, 0.0, "no age: the default");

    // Rendered as a bare file (the default scene framed on it) and from a scene file.
    let scene = dir.join("houdini.toml");
    std::fs::write(&scene, scene_reading("houdini.ply")).unwrap();
    for (input, png) in [(&path, "bare.png"), (&scene, "scene.png")] {
        let (png, none) = (dir.join(png), dir.join(format!("none_{png}")));
        for (technique, out) in [("dom", &png), ("none", &none)] {
            ok(&smokeshadow(&[
                "render",
                input.to_str().unwrap(),
                "--size",
                "160x120",
                "--technique",
                technique,
                "-o",
                out.to_str().unwrap(),
            ]));
        }
        // Smoke covers the middle of the frame: the centre pixels are not the background, and
        // the block shadows itself (dom darker than none somewhere in the middle).
        let (img, unshadowed) = (
            image::open(&png).unwrap().into_rgb8(),
            image::open(&none).unwrap().into_rgb8(),
        );
        // The background at the top edge is darker than the lit smoke somewhere in the middle.
        let background = img.get_pixel(80, 1).0[1];
        let brightest = (50..110)
            .flat_map(|x| (30..90).map(move |y| (x, y)))
            .map(|(x, y)| img.get_pixel(x, y).0[1])
            .max()
            .unwrap();
        assert!(
            brightest > background + 40,
            "{input:?}: {brightest} vs {background}"
        );
        let darker = (50..110)
            .flat_map(|x| (30..90).map(move |y| (x, y)))
            .filter(|&(x, y)| {
                let (s, n) = (img.get_pixel(x, y).0, unshadowed.get_pixel(x, y).0);
                u32::from(s[1]) + 20 < u32::from(n[1])
            })
            .count();
        assert!(darker > 100, "{input:?}: {darker} self-shadowed pixels");
    }
}

#[test]
fn missing_optional_properties_take_the_scenes_defaults() {
    let dir = scratch("particles_defaults");
    let path = dir.join("positions.csv");
    std::fs::write(&path, "x,y,z\n0,1,0\n0.5,1.5,-0.25\n").unwrap();
    let defaults = Defaults {
        radius_m: 0.3,
        density_per_m: 4.0,
        albedo: glam::Vec3::new(0.5, 0.6, 0.7),
    };
    let read = particles::read(&smokeshadow::files::Files::host(), &path, &defaults).unwrap();
    assert_eq!(read.len(), 2);
    assert_eq!(read[1].position, glam::Vec3::new(0.5, 1.5, -0.25));
    assert_eq!(
        (read[1].radius_m, read[1].density_per_m, read[1].albedo),
        (0.3, 4.0, defaults.albedo)
    );
    // Blender writes colours as uchar: 0..255 maps to 0..1.
    let blender = dir.join("blender.ply");
    std::fs::write(
        &blender,
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
         property float z\nproperty float nx\nproperty uchar red\nproperty uchar green\n\
         property uchar blue\nproperty uchar alpha\nend_header\n1 2 3 0 255 51 0 255\n",
    )
    .unwrap();
    let read = particles::read(&smokeshadow::files::Files::host(), &blender, &defaults).unwrap();
    assert_eq!(read[0].albedo, glam::Vec3::new(1.0, 0.2, 0.0));
    assert_eq!(read[0].radius_m, 0.3);
}

#[test]
fn a_sequence_is_written_and_the_scene_time_picks_its_frame() {
    let dir = scratch("particles_sequence");
    let pattern = dir.join("smoke.%04d.csv");
    let stdout = ok(&smokeshadow(&[
        "particles",
        "-o",
        pattern.to_str().unwrap(),
        "--frames",
        "46..48",
        "--fps",
        "12",
    ]));
    assert!(stdout.contains("frames 46..=48"), "{stdout}");
    for f in 46..=48 {
        assert!(dir.join(format!("smoke.{f:04}.csv")).is_file(), "frame {f}");
    }
    // Frame 47 at 12 fps is t = 47/12 s: what the emitter gives at that time.
    let mut scene = Scene::thesis_plume();
    scene.sim.duration_s = 47.0 / 12.0;
    let expected = simulate(&scene);
    let text = scene_reading("smoke.%04d.csv")
        .replace("[particles]\n", "[particles]\nframe_rate_hz = 12.0\n");
    let text = text.replace(
        "duration_s = 8.0",
        &format!("duration_s = {}", 47.0f32 / 12.0),
    );
    let toml = dir.join("sequence.toml");
    std::fs::write(&toml, text).unwrap();
    let loaded = Scene::load(&toml, &smokeshadow::files::Files::host()).unwrap();
    let source = loaded.particles.as_ref().unwrap();
    assert_eq!(source.frame_at(loaded.sim.duration_s), 47);
    let read = particles::scene_particles(&loaded).unwrap();
    assert_eq!(bits(&read), bits(&expected));
    // A frame that is not there is named.
    let mut late = loaded.clone();
    late.sim.duration_s = 5.0;
    let err = particles::scene_particles(&late).unwrap_err().to_string();
    assert!(err.contains("smoke.0060.csv"), "{err}");
}

/// One error line from reading `contents` as `name`.
fn read_error(dir: &Path, name: &str, contents: &[u8]) -> String {
    let path = dir.join(name);
    std::fs::write(&path, contents).unwrap();
    let err = particles::read(
        &smokeshadow::files::Files::host(),
        &path,
        &Defaults::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(!err.contains('\n'), "one line: {err}");
    assert!(
        err.contains(&*path.to_string_lossy()),
        "names the file: {err}"
    );
    err
}

#[test]
fn bad_particle_files_get_one_line_naming_the_element_and_property() {
    let dir = scratch("particles_bad");
    let header = |props: &str, n: usize| {
        format!("ply\nformat ascii 1.0\nelement vertex {n}\n{props}end_header\n")
    };
    let xyz_r = "property float x\nproperty float y\nproperty float z\nproperty float radius\n";

    // A required property missing.
    let err = read_error(
        &dir,
        "no_z.ply",
        format!(
            "{}1 2 0.5\n",
            header(
                "property float x\nproperty float y\nproperty float radius\n",
                1
            )
        )
        .as_bytes(),
    );
    assert!(err.contains("element vertex has no property z"), "{err}");
    // NaN (binary: ASCII PLY has no spelling of NaN).
    let mut nan = b"ply\nformat binary_little_endian 1.0\nelement vertex 2\n".to_vec();
    nan.extend_from_slice(xyz_r.as_bytes());
    nan.extend_from_slice(b"end_header\n");
    for v in [0f32, 0.0, 0.0, 0.1, 1.0, f32::NAN, 0.0, 0.1] {
        nan.extend_from_slice(&v.to_le_bytes());
    }
    let err = read_error(&dir, "nan.ply", &nan);
    assert!(err.contains("element vertex 1: property y = NaN"), "{err}");
    // A number that is not one.
    let err = read_error(
        &dir,
        "word.ply",
        format!("{}0 0 0 0.1\n1 high 0 0.1\n", header(xyz_r, 2)).as_bytes(),
    );
    assert!(
        err.contains("element vertex") && err.contains("high"),
        "{err}"
    );
    // A negative radius, in CSV.
    let err = read_error(&dir, "neg.csv", b"x,y,z,pscale\n0,0,0,0.2\n0,1,0,-0.5\n");
    assert!(
        err.contains("row 1 (line 3): property radius = -0.5: must be > 0"),
        "{err}"
    );
    // Empty files, and a header without particles.
    let err = read_error(&dir, "empty.ply", b"");
    assert!(err.contains("the file is empty"), "{err}");
    let err = read_error(&dir, "empty.csv", b"");
    assert!(err.contains("the file is empty"), "{err}");
    let err = read_error(&dir, "none.ply", header(xyz_r, 0).as_bytes());
    assert!(err.contains("element vertex has no particles"), "{err}");
    // A truncated binary PLY: the file ends inside particle 1's radius.
    let mut binary = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n".to_vec();
    binary.extend_from_slice(xyz_r.as_bytes());
    binary.extend_from_slice(b"end_header\n");
    for v in [0f32, 1.0, 2.0, 0.25, 3.0, 4.0, 5.0] {
        binary.extend_from_slice(&v.to_le_bytes());
    }
    binary.extend_from_slice(&[0, 0]);
    let err = read_error(&dir, "truncated.ply", &binary);
    assert!(
        err.contains("element vertex 1 of 3: property radius: the file ends there"),
        "{err}"
    );
    // Not a PLY at all, and an unknown extension.
    let err = read_error(&dir, "text.ply", b"hello\n");
    assert!(err.contains("not a PLY file"), "{err}");
    let err = read_error(&dir, "smoke.vdb", b"x");
    assert!(err.contains("unknown format"), "{err}");

    // Through the CLI: one `error:` line, exit 2, for a scene whose file is bad or missing.
    for (file, needle) in [
        ("truncated.ply", "the file ends there"),
        ("missing.ply", "cannot read particle file"),
    ] {
        let scene = dir.join(format!("{file}.toml"));
        std::fs::write(&scene, scene_reading(file)).unwrap();
        let out = smokeshadow(&["render", scene.to_str().unwrap(), "-o", "/dev/null/x.png"]);
        assert_eq!(out.status.code(), Some(2));
        let lines = error_lines(&out);
        assert_eq!(lines.len(), 1, "{lines:#?}");
        assert!(
            lines[0].starts_with("error: ") && lines[0].contains(needle),
            "{lines:?}"
        );
    }
    // Bare files the framing cannot take: one line about the particles, not about a scene
    // field the user never wrote (a file at 1e30 m once said "light.intensity = inf").
    for (file, contents, needle) in [
        (
            "far.csv",
            "x,y,z,radius\n1e30,0,0,0.1\n1e30,1,0,0.1\n",
            "its particles reach 1e30 m from the origin",
        ),
        (
            "speck.csv",
            "x,y,z,radius\n1e5,0,0,1e-4\n1e5,0,1e-4,1e-4\n",
            "too small to frame in f32 there",
        ),
    ] {
        let path = dir.join(file);
        std::fs::write(&path, contents).unwrap();
        let out = smokeshadow(&["render", path.to_str().unwrap(), "-o", "/dev/null/x.png"]);
        assert_eq!(out.status.code(), Some(2));
        let lines = error_lines(&out);
        assert_eq!(lines.len(), 1, "{lines:#?}");
        assert!(
            lines[0].starts_with("error: ") && lines[0].contains(needle) && lines[0].contains(file),
            "{lines:?}"
        );
        assert!(!lines[0].contains("light."), "{lines:?}");
    }
    // A scene with both a particle file and an emitter is refused.
    let both = format!("{}\n[emitter]\ncount = 10\n", scene_reading("p.ply"));
    let err = Scene::from_toml_str(&both, "both.toml")
        .unwrap_err()
        .to_string();
    assert!(err.contains("both [particles] and an emitter"), "{err}");
}

#[test]
fn baselines_of_your_own_particles_bless_check_and_notice_a_changed_file() {
    let dir = scratch("particles_baselines");
    let ply = dir.join("mine.ply");
    ok(&smokeshadow(&["particles", "-o", ply.to_str().unwrap()]));
    let baselines = dir.join("baselines");
    let run = |mode: &str| {
        smokeshadow(&[
            "baseline",
            mode,
            "--scene",
            ply.to_str().unwrap(),
            "--technique",
            "none",
            "--dir",
            baselines.to_str().unwrap(),
            "--out",
            dir.join("out").to_str().unwrap(),
        ])
    };
    let blessed = ok(&run("--bless"));
    assert!(baselines.join("mine/none.png").is_file(), "{blessed}");
    let checked = run("--check");
    assert_eq!(
        checked.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&checked.stdout)
    );
    // The scene's identity includes its particles: moving one makes the baseline stale.
    let mut moved = particles::read(
        &smokeshadow::files::Files::host(),
        &ply,
        &Defaults::default(),
    )
    .unwrap();
    moved[0].position.y += 0.5;
    particles::write(&ply, &moved, None).unwrap();
    let stale = run("--check");
    let text = String::from_utf8_lossy(&stale.stdout).into_owned()
        + &String::from_utf8_lossy(&stale.stderr);
    assert_eq!(stale.status.code(), Some(1), "{text}");
    assert!(text.contains("the scene mine changed since"), "{text}");
}
