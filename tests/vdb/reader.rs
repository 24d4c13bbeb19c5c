//! The reader on the real OpenVDB files in tests/data/volumes (see its README.md) and on files
//! synthesized by a small writer (tests/common/vdb_writer.rs) for the branches the real files do
//! not use: no compression, zip, every per-node metadata mode, half floats, blosc variants,
//! tiles, transforms, duplicate names and instances. When it was written the reader was also
//! compared voxel by voxel with the vdb-rs crate (0.6.0) on the three real grids: the same
//! active voxels and the same f32 bits at each; the statistics asserted below are those.

use super::vdb_writer::*;
use glam::{DVec3, IVec3, UVec3};
use smokeshadow::medium::vdb::*;

fn read(bytes: &[u8], name: &str) -> Result<FloatGrid, VdbError> {
    read_float_grid(bytes, name, &Limits::default())
}

fn err(bytes: &[u8], name: &str) -> String {
    match read(bytes, name) {
        Ok(g) => panic!(
            "expected an error reading {name:?}, got a grid of {} voxels",
            g.active_voxels
        ),
        Err(e) => e.to_string(),
    }
}

/// Checks a grid against writer-side statistics from list_grids, the README facts, and the sum
/// of its densities as vdb-rs read them (see the header).
fn check_real(
    file: &str,
    name: &str,
    active: u64,
    min: [i32; 3],
    max: [i32; 3],
    sum_by_vdb_rs: f64,
) -> FloatGrid {
    let bytes = real_file(file);
    let g = read(&bytes, name).unwrap();
    assert_eq!(g.active_voxels, active, "{file} {name}");
    assert_eq!(g.index_min, IVec3::from(min));
    assert_eq!(g.dims, (IVec3::from(max) - IVec3::from(min) + 1).as_uvec3());
    assert_eq!(g.values.len() as u32, g.dims.x * g.dims.y * g.dims.z);
    assert_eq!(g.compression, "blosc(lz4)");
    assert!(!g.saved_as_half);
    assert_eq!(g.background, 0.0);
    let info = list_grids(&bytes)
        .unwrap()
        .into_iter()
        .find(|i| i.name == name)
        .unwrap();
    assert_eq!(info.file_active_voxels, Some(active as i64));
    assert_eq!(
        info.file_index_bbox,
        Some((IVec3::from(min), IVec3::from(max)))
    );
    assert_eq!(info.compression, "blosc + active mask");
    // Densities lie in [0, 1]; every voxel outside the active set is the background 0.
    assert!(g.values.iter().all(|v| (0.0..=1.0).contains(v)));
    let (lo, hi, sum) = stats(&g.values);
    assert_eq!(
        lo, 0.0,
        "{file} {name}: inactive voxels hold the background"
    );
    assert!(hi > 0.7 && hi <= 1.0, "{file} {name}: max {hi}");
    // The f64 sum of ~1e5 f32 values in the same order: equal to 1e-4 of the fourth decimal.
    assert!(
        (sum - sum_by_vdb_rs).abs() < 1e-3,
        "{file} {name}: sum {sum}, vdb-rs {sum_by_vdb_rs}"
    );
    g
}

fn stats(values: &[f32]) -> (f32, f32, f64) {
    let lo = values.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = values.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    (lo, hi, values.iter().map(|&v| v as f64).sum())
}

#[test]
fn smoke_000003_density_matches_readme_and_writer_metadata() {
    let g = check_real(
        "openusd_smoke_000003.vdb",
        "density",
        90_197,
        [1, 1, 3],
        [51, 49, 98],
        29401.8865,
    );
    assert_eq!(g.dims, UVec3::new(51, 49, 96));
    // ScaleTranslateMap: voxel size and offset as stored in the file.
    let m = g.world_from_index;
    let voxel = DVec3::new(m.matrix3.x_axis.x, m.matrix3.y_axis.y, m.matrix3.z_axis.z);
    assert!(
        (voxel - DVec3::new(0.132601, 0.132903, 0.131697))
            .abs()
            .max_element()
            < 1e-5,
        "{voxel}"
    );
    assert!(
        (m.translation - DVec3::new(-3.447625, -3.322587, -2.640232))
            .abs()
            .max_element()
            < 1e-5
    );
    assert_eq!(m.matrix3.x_axis.y, 0.0);
}

#[test]
fn density_and_heat_match_readme_and_writer_metadata() {
    let f = "openusd_densityAndHeat.vdb";
    check_real(f, "density", 6_124, [1, 1, 31], [23, 23, 72], 399.7241);
    check_real(f, "heat", 5_224, [2, 2, 31], [23, 22, 62], 276.5203);
    let names: Vec<String> = list_grids(&real_file(f))
        .unwrap()
        .into_iter()
        .map(|i| i.name)
        .collect();
    assert_eq!(names, ["density", "heat"]);
}

#[test]
fn empty_file_reads_float_grids_empty_and_refuses_others_by_name() {
    let bytes = real_file("openusd_smoke_000001_empty.vdb");
    let infos = list_grids(&bytes).unwrap();
    let kinds: Vec<(String, String)> = infos
        .iter()
        .map(|i| (i.name.clone(), i.value_type.clone()))
        .collect();
    let expect = [
        ("density", "float"),
        ("shadow", "float"),
        ("velocity", "vec3s"),
        ("obstacles", "int32"),
    ];
    assert_eq!(kinds, expect.map(|(a, b)| (a.to_string(), b.to_string())));
    for name in ["density", "shadow"] {
        let g = read(&bytes, name).unwrap();
        assert_eq!(
            (g.active_voxels, g.dims, g.values.len()),
            (0, UVec3::ZERO, 0)
        );
        assert_eq!(g.compression, "blosc");
    }
    assert_eq!(
        err(&bytes, "velocity"),
        "grid \"velocity\" holds vec3s values; only float grids can be read"
    );
    assert_eq!(
        err(&bytes, "obstacles"),
        "grid \"obstacles\" holds int32 values; only float grids can be read"
    );
}

#[test]
fn unknown_grid_name_lists_what_the_file_holds() {
    let bytes = real_file("openusd_smoke_000001_empty.vdb");
    assert_eq!(
        err(&bytes, "temperature"),
        "grid \"temperature\" not found; the file holds: density (float), shadow (float), velocity (vec3s), obstacles (int32)"
    );
}

#[test]
fn truncated_files_err_with_truncated() {
    let bytes = real_file("openusd_smoke_000003.vdb");
    for len in [0, 3, 8, 20, 60, 200, 600, 5_000, 100_000, bytes.len() - 1] {
        let e = err(&bytes[..len], "density");
        if len < 8 {
            assert!(e.starts_with("not an OpenVDB file"), "{len}: {e}");
        } else {
            assert!(e.starts_with("truncated at byte"), "{len}: {e}");
        }
    }
    let e = err(&bytes[..bytes.len() - 1], "density");
    assert!(e.contains("remain"), "{e}");
}

#[test]
fn not_vdb_and_versions_are_refused() {
    assert!(err(b"hello world, this is not a vdb file", "x").starts_with("not an OpenVDB file"));
    let mut s = Stats::default();
    let g = Grid::float("d");
    for (version, ok) in [(221, false), (222, true), (225, true), (226, false)] {
        let bytes = write_file_with(
            std::slice::from_ref(&g),
            &FileOpts {
                version,
                has_offsets: true,
            },
            &mut s,
        );
        match read(&bytes, "d") {
            Ok(_) => assert!(ok, "{version}"),
            Err(e) => {
                assert!(!ok, "{version}: {e}");
                assert!(
                    e.to_string()
                        .contains(&format!("version {version} is not supported")),
                    "{e}"
                );
            }
        }
    }
    let bytes = write_file_with(
        &[g],
        &FileOpts {
            version: 224,
            has_offsets: false,
        },
        &mut s,
    );
    assert!(err(&bytes, "d").contains("no grid offsets"));
}

// ---------------------------------------------------------------------------------------------
// Comparison with vdb-rs 0.6.0

/// Reads a synthesized grid and compares it with the writer's voxels, voxel by voxel.
fn check_synth(g: &Grid, bytes: &[u8]) -> FloatGrid {
    let out = read(bytes, &g.name).unwrap_or_else(|e| panic!("{e}"));
    let expect = expected_voxels(g);
    assert_eq!(out.active_voxels, expect.len() as u64);
    let mut lo = IVec3::MAX;
    let mut hi = IVec3::MIN;
    for (p, v) in &expect {
        let p = IVec3::from(*p);
        lo = lo.min(p);
        hi = hi.max(p);
        let got = out.value_at(p).unwrap();
        assert_eq!(
            got.to_bits(),
            v.to_bits(),
            "at {p}: got {got}, expected {v}"
        );
    }
    if !expect.is_empty() {
        assert_eq!((out.index_min, out.dims), (lo, (hi - lo + 1).as_uvec3()));
    }
    let inactive = out
        .values
        .iter()
        .filter(|v| v.to_bits() == g.background.to_bits())
        .count();
    assert!(inactive + expect.len() >= out.values.len());
    out
}

/// Leaves that make the writer use every per-node metadata byte 0..=6 (with background 2.0).
fn leaves_for_every_mode() -> Vec<Leaf> {
    let active = |n: usize| n.is_multiple_of(3);
    let value = |n: usize| n as f32 * 0.25 - 7.0;
    let modes: [&dyn Fn(usize) -> f32; 7] = [
        &|_| 2.0,                                 // 0: inactive == background
        &|_| -2.0,                                // 1: inactive == -background
        &|_| 7.5,                                 // 2: one other inactive value
        &|n| if n % 2 == 0 { -2.0 } else { 2.0 }, // 3: -bg and +bg
        &|n| if n % 2 == 0 { 9.0 } else { 2.0 },  // 4: bg and another value
        &|n| if n % 2 == 0 { 9.0 } else { -3.0 }, // 5: two other values
        &|n| n as f32,                            // 6: many inactive values
    ];
    let mut leaves = Vec::new();
    for (i, inactive) in modes.iter().enumerate() {
        let origin = [8 * i as i32, -16, 24];
        leaves.push(leaf(origin, active, |n| {
            if active(n) { value(n) } else { inactive(n) }
        }));
    }
    // A fully active leaf and one without active voxels (nothing in its buffer when masked).
    leaves.push(leaf([0, 0, 0], |_| true, |n| n as f32));
    leaves.push(leaf([64, 0, 0], |_| false, |_| 2.0));
    leaves
}

#[test]
fn uncompressed_zip_and_mask_compression_every_mode() {
    for compression in [
        0,
        ACTIVE_MASK,
        ZIP,
        ZIP | ACTIVE_MASK,
        BLOSC,
        BLOSC | ACTIVE_MASK,
    ] {
        let mut g = Grid::float("density");
        g.compression = compression;
        g.background = 2.0;
        g.leaves = leaves_for_every_mode();
        let mut s = Stats::default();
        let bytes = write_file(std::slice::from_ref(&g), &mut s);
        if compression & ACTIVE_MASK != 0 {
            assert!(
                s.modes.iter().all(|&m| m > 0),
                "writer did not use every mode: {s:?}"
            );
        }
        let out = check_synth(&g, &bytes);
        let name = match compression & (ZIP | BLOSC) {
            0 => "none",
            ZIP => "zip",
            _ => "blosc(lz4)",
        };
        assert_eq!(out.compression, name);
        assert_eq!(out.background, 2.0);
    }
}

#[test]
fn zip_stored_chunks_are_read() {
    // Random-looking values do not deflate, so the writer stores them (negative byte count).
    let mut g = Grid::float("noise");
    g.compression = ZIP;
    let mut x = 0x1234_5678u32;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        f32::from_bits(x & 0xbfff_ffff) // never NaN or infinite
    };
    let values: Vec<f32> = (0..512).map(|_| next()).collect();
    g.leaves = vec![leaf([8, 8, 8], |n| n % 2 == 0, |n| values[n])];
    let mut s = Stats::default();
    let bytes = write_file(std::slice::from_ref(&g), &mut s);
    assert!(s.stored_chunks > 0, "{s:?}");
    check_synth(&g, &bytes);
}

#[test]
fn half_floats_are_widened_exactly_for_every_bit_pattern() {
    // 128 fully active leaves hold all 65536 half bit patterns (NaNs compared by bits too).
    let mut g = Grid::float("h");
    g.half = true;
    for i in 0..128 {
        let patterns: Vec<f32> = (0..512)
            .map(|n| half::f16::from_bits((i * 512 + n) as u16).to_f32())
            .collect();
        g.leaves
            .push(leaf([8 * i, 0, 0], |_| true, |n| patterns[n]));
    }
    g.leaves.push(leaf(
        [0, 8, 0],
        |n| n < 5,
        |n| if n < 5 { 1.5 } else { 0.25 },
    ));
    let mut s = Stats::default();
    let bytes = write_file(std::slice::from_ref(&g), &mut s);
    let out = read(&bytes, "h").unwrap();
    assert!(out.saved_as_half);
    for i in 0..128i32 {
        for n in 0..512usize {
            let bits = (i as usize * 512 + n) as u16;
            let p = IVec3::new(
                8 * i + (n >> 6) as i32,
                ((n >> 3) & 7) as i32,
                (n & 7) as i32,
            );
            let got = out.value_at(p).unwrap();
            let want = half::f16::from_bits(bits).to_f32();
            if want.is_nan() {
                assert!(got.is_nan(), "{bits:#06x}");
            } else {
                assert_eq!(got.to_bits(), want.to_bits(), "{bits:#06x}");
            }
        }
    }
    // Half with zip and mask compression (inactive values stored full size).
    let mut g = Grid::float("h2");
    g.half = true;
    g.compression = ZIP | ACTIVE_MASK;
    g.background = 2.0;
    g.leaves = leaves_for_every_mode();
    let bytes = write_file(std::slice::from_ref(&g), &mut s);
    check_synth(&g, &bytes);
}

#[test]
fn blosc_variants() {
    let values: Vec<f32> = (0..512).map(|n| ((n * 37) % 101) as f32 * 0.01).collect();
    let variants = [
        BloscOpts::default(),
        BloscOpts {
            codec: Codec::Zlib,
            ..Default::default()
        },
        BloscOpts {
            memcpyed: true,
            ..Default::default()
        },
        BloscOpts {
            shuffle: false,
            ..Default::default()
        },
        BloscOpts {
            dont_split: true,
            ..Default::default()
        },
        BloscOpts {
            blocksize: 600,
            ..Default::default()
        }, // 4 blocks, last one a leftover
        BloscOpts {
            blocksize: 512,
            codec: Codec::Zlib,
            ..Default::default()
        }, // splits per block
        BloscOpts {
            blocksize: 100,
            shuffle: true,
            ..Default::default()
        },
    ];
    for (i, b) in variants.into_iter().enumerate() {
        let mut g = Grid::float("v");
        g.blosc = b.clone();
        g.leaves = vec![
            leaf([0, 0, 0], |n| n % 5 != 1, |n| values[n]),
            leaf([8, 0, 0], |_| true, |n| values[n]),
        ];
        let mut s = Stats::default();
        let bytes = write_file(std::slice::from_ref(&g), &mut s);
        let out = check_synth(&g, &bytes);
        let want = match (b.memcpyed, b.codec) {
            (true, _) => "blosc",
            (false, Codec::Zlib) => "blosc(zlib)",
            _ => "blosc(lz4)",
        };
        assert_eq!(out.compression, want, "variant {i}: {b:?}");
    }
}

#[test]
fn blosc_refusals_name_the_codec_or_filter() {
    let values: Vec<f32> = (0..512).map(|n| (n % 7) as f32).collect();
    let cases = [
        (
            BloscOpts {
                codec: Codec::Code(2),
                ..Default::default()
            },
            "unsupported blosc codec snappy",
        ),
        (
            BloscOpts {
                codec: Codec::Code(0),
                ..Default::default()
            },
            "unsupported blosc codec blosclz",
        ),
        (
            BloscOpts {
                codec: Codec::Code(4),
                ..Default::default()
            },
            "unsupported blosc codec zstd",
        ),
        (
            BloscOpts {
                bitshuffle: true,
                ..Default::default()
            },
            "bit-shuffle",
        ),
    ];
    for (b, want) in cases {
        let mut g = Grid::float("v");
        g.blosc = b;
        g.leaves = vec![leaf([0, 0, 0], |_| true, |n| values[n])];
        let bytes = write_file(&[g], &mut Stats::default());
        let e = err(&bytes, "v");
        assert!(e.contains(want), "{e}");
    }
}

#[test]
fn tiles_are_expanded() {
    let mut g = Grid::float("t");
    g.compression = ZIP | ACTIVE_MASK;
    g.background = 0.5;
    g.leaves = vec![leaf([0, 0, 0], |n| n % 2 == 0, |n| n as f32)];
    g.tiles4 = vec![
        Tile {
            origin: [8, 0, 0],
            value: 3.0,
            active: true,
        },
        Tile {
            origin: [16, 8, 120],
            value: 4.0,
            active: true,
        },
        Tile {
            origin: [8, 8, 0],
            value: 9.0,
            active: false,
        },
    ];
    g.root_tiles = vec![Tile {
        origin: [4096, 0, 0],
        value: 7.0,
        active: false,
    }];
    let bytes = write_file(std::slice::from_ref(&g), &mut Stats::default());
    let out = check_synth(&g, &bytes);
    assert_eq!(out.value_at(IVec3::new(9, 9, 1)), Some(0.5)); // inactive tile -> background
    assert_eq!(
        (out.index_min, out.dims),
        (IVec3::ZERO, UVec3::new(24, 16, 128))
    );

    // A 128³ tile in a node 5, next to a leaf in another root child (written out of order).
    let mut g = Grid::float("big");
    g.tiles5 = vec![Tile {
        origin: [-128, 0, 0],
        value: 1.25,
        active: true,
    }];
    g.leaves = vec![
        leaf([0, 8, 8], |n| n == 0, |_| 6.0),
        leaf([-136, 16, 16], |n| n == 511, |_| 5.0),
    ];
    g.reverse_root_topology = true;
    let bytes = write_file(std::slice::from_ref(&g), &mut Stats::default());
    let out = read(&bytes, "big").unwrap();
    assert_eq!(out.active_voxels, 128 * 128 * 128 + 2);
    assert_eq!(
        (out.index_min, out.dims),
        (IVec3::new(-129, 0, 0), UVec3::new(130, 128, 128))
    );
    assert_eq!(out.value_at(IVec3::new(0, 8, 8)), Some(6.0));
    assert_eq!(out.value_at(IVec3::new(-129, 23, 23)), Some(5.0));
    assert_eq!(out.value_at(IVec3::new(-1, 127, 127)), Some(1.25));
    assert_eq!(out.value_at(IVec3::new(-129, 0, 0)), Some(0.0));
    assert_eq!(out.value_at(IVec3::new(0, 0, 0)), Some(0.0));

    // An active root tile is 4096³ voxels: far over the limit, refused before allocating.
    let mut g = Grid::float("root");
    g.root_tiles = vec![Tile {
        origin: [0, 0, 0],
        value: 1.0,
        active: true,
    }];
    let bytes = write_file(&[g], &mut Stats::default());
    assert_eq!(
        err(&bytes, "root"),
        "grid \"root\" has more than 33554432 active voxels, the dense-voxel limit"
    );
}

#[test]
fn dense_limit_is_enforced_with_a_clear_message() {
    let mut g = Grid::float("far");
    g.leaves = vec![
        leaf([0, 0, 0], |n| n == 0, |_| 1.0),
        leaf([592, 592, 592], |n| n == 511, |_| 1.0),
    ];
    let bytes = write_file(&[g], &mut Stats::default());
    assert_eq!(
        err(&bytes, "far"),
        "dense grid would be 600x600x600 = 216000000 voxels, more than the limit of 33554432"
    );
    let small = Limits {
        max_dense_voxels: 1000,
    };
    let ok = read_float_grid(
        &bytes,
        "far",
        &Limits {
            max_dense_voxels: 216_000_000,
        },
    );
    assert_eq!(ok.map(|g| g.active_voxels), Ok(2));
    assert!(read_float_grid(&bytes, "far", &small).is_err());
}

#[test]
fn transforms() {
    let rot = [
        0.0, 2.0, 0.0, 0.0, -2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 10.0, 20.0, 30.0, 1.0,
    ];
    let cases = [
        (Map::UniformScale(0.25), DVec3::splat(0.25)),
        (
            Map::ScaleTranslate([1.0, 2.0, 3.0], [-1.0, 0.5, 4.0]),
            DVec3::new(0.0, 2.5, 7.0),
        ),
        (Map::Translation([5.0, 6.0, 7.0]), DVec3::new(6.0, 7.0, 8.0)),
        (
            Map::Affine(rot),
            DVec3::new(10.0 - 2.0, 20.0 + 2.0, 30.0 + 2.0),
        ),
    ];
    for (map, world_of_111) in cases {
        let mut g = Grid::float("m");
        g.map = map.clone();
        let bytes = write_file(&[g], &mut Stats::default());
        let out = read(&bytes, "m").unwrap();
        let w = out.world_from_index.transform_point3(DVec3::ONE);
        assert!(
            (w - world_of_111).abs().max_element() < 1e-12,
            "{map:?}: {w}"
        );
    }
    let mut g = Grid::float("frustum");
    g.map = Map::Other("NonlinearFrustumMap");
    let bytes = write_file(&[g], &mut Stats::default());
    assert_eq!(
        err(&bytes, "frustum"),
        "grid \"frustum\" uses the transform NonlinearFrustumMap; only scale, translation and affine maps are supported"
    );
}

#[test]
fn duplicate_names_and_instances() {
    let mut a = Grid::float("d\u{1e}0");
    a.leaves = vec![leaf([0, 0, 0], |n| n == 0, |_| 1.0)];
    let mut b = Grid::float("d\u{1e}1");
    b.leaves = vec![leaf([0, 0, 0], |n| n == 0, |_| 2.0)];
    let mut inst = Grid::float("copy");
    inst.instance_parent = "d\u{1e}1".to_string();
    inst.map = Map::UniformScale(3.0);
    let bytes = write_file(&[a, b, inst], &mut Stats::default());
    let names: Vec<String> = list_grids(&bytes)
        .unwrap()
        .into_iter()
        .map(|i| i.name)
        .collect();
    assert_eq!(names, ["d[0]", "d[1]", "copy"]);
    let at0 = |g: FloatGrid| g.value_at(IVec3::ZERO);
    assert_eq!(read(&bytes, "d").map(at0), Ok(Some(1.0)));
    assert_eq!(read(&bytes, "d[0]").map(at0), Ok(Some(1.0)));
    assert_eq!(read(&bytes, "d[1]").map(at0), Ok(Some(2.0)));
    let copy = read(&bytes, "copy").unwrap();
    assert_eq!(
        (copy.name.as_str(), copy.value_at(IVec3::ZERO)),
        ("copy", Some(2.0))
    );
    assert_eq!(copy.world_from_index.matrix3.x_axis.x, 3.0);
    let info = list_grids(&bytes).unwrap();
    assert_eq!(info[2].instance_parent.as_deref(), Some("d[1]"));
    assert!(err(&bytes, "d[2]").contains("not found"));
}
