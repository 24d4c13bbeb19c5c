//! The OpenVDB reader (`smokeshadow::medium::vdb`) on real files written by other tools
//! (`tests/data/volumes/`, from OpenUSD's test data): what it reads agrees with what the writer
//! recorded about its own grids (active voxel counts and index boxes in the grid metadata), grids
//! it cannot read are refused by name, and the real smoke becomes a medium whose GPU march
//! agrees with the f64 mirror and converges.

use smokeshadow::Wait;
mod common;
#[path = "vdb/reader.rs"]
mod reader;
#[path = "common/vdb_writer.rs"]
mod vdb_writer;

use std::path::PathBuf;

use glam::{DAffine3, DVec3, IVec3, UVec3, Vec3};
use smokeshadow::gpu::MemoryLedger;
use smokeshadow::medium::gpu_grid::{GpuGrid, GridMarch};
use smokeshadow::medium::grid::{DensityGrid, GridError};
use smokeshadow::medium::vdb::{self, Limits, VdbError};

fn data(name: &str) -> Vec<u8> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/volumes")
        .join(name);
    std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

const SMOKE: &str = "openusd_smoke_000003.vdb";
const TWO_GRIDS: &str = "openusd_densityAndHeat.vdb";
const EMPTY: &str = "openusd_smoke_000001_empty.vdb";

#[test]
fn every_float_grid_matches_its_writers_own_metadata() {
    // The writer stored each grid's active voxel count and index box as metadata; the reader
    // counts and bounds the voxels it decodes, independently of that metadata.
    let mut checked = 0;
    for (file, expected) in [
        (SMOKE, vec![("density", 90_197)]),
        (TWO_GRIDS, vec![("density", 6_124), ("heat", 5_224)]),
    ] {
        let bytes = data(file);
        let infos = vdb::list_grids(&bytes).unwrap();
        for (name, count) in expected {
            let info = infos.iter().find(|g| g.name == name).unwrap();
            assert_eq!(info.value_type, "float");
            let grid = vdb::read_float_grid(&bytes, name, &Limits::default()).unwrap();
            assert_eq!(grid.active_voxels, count, "{file}: {name}");
            assert_eq!(
                info.file_active_voxels,
                Some(count as i64),
                "{file}: {name}"
            );
            let (lo, hi) = info.file_index_bbox.unwrap();
            assert_eq!(grid.index_min, lo, "{file}: {name}");
            assert_eq!(
                grid.index_min + grid.dims.as_ivec3() - IVec3::ONE,
                hi,
                "{file}: {name}"
            );
            // A fog volume's densities: finite, in 0..1, zero background, and no more non-zero
            // voxels than active ones.
            assert_eq!(grid.background, 0.0);
            assert!(
                grid.values
                    .iter()
                    .all(|v| v.is_finite() && (0.0..=1.0).contains(v))
            );
            let nonzero = grid.values.iter().filter(|v| **v != 0.0).count() as u64;
            assert!(nonzero <= grid.active_voxels && nonzero > grid.active_voxels / 2);
            checked += 1;
        }
    }
    assert_eq!(checked, 3);
}

#[test]
fn the_smoke_frame_has_the_box_and_voxel_size_its_readme_gives() {
    let grid = vdb::read_float_grid(&data(SMOKE), "density", &Limits::default()).unwrap();
    assert_eq!(grid.index_min, IVec3::new(1, 1, 3));
    assert_eq!(grid.dims, UVec3::new(51, 49, 96));
    assert_eq!(grid.compression, "blosc(lz4)");
    // Voxels of about 0.13 file units on every axis.
    for axis in [
        grid.world_from_index.matrix3.x_axis,
        grid.world_from_index.matrix3.y_axis,
        grid.world_from_index.matrix3.z_axis,
    ] {
        assert!((axis.length() - 0.132).abs() < 0.002, "{axis}");
    }
}

#[test]
fn grids_that_are_not_float_densities_are_refused_by_name() {
    let bytes = data(EMPTY);
    // The empty file's float grid reads as an empty medium.
    let density = vdb::read_float_grid(&bytes, "density", &Limits::default()).unwrap();
    assert_eq!(density.dims, UVec3::ZERO);
    assert_eq!(density.active_voxels, 0);
    let medium = DensityGrid::from_vdb(&density, DAffine3::IDENTITY, 1.0).unwrap();
    assert_eq!(medium.world_bounds(), None);
    for (name, value_type) in [("velocity", "vec3s"), ("obstacles", "int32")] {
        let err = vdb::read_float_grid(&bytes, name, &Limits::default()).unwrap_err();
        assert!(matches!(err, VdbError::NotFloat { .. }), "{err}");
        let line = err.to_string();
        assert!(line.contains(name) && line.contains(value_type), "{line}");
    }
    let err = vdb::read_float_grid(&bytes, "smoke", &Limits::default()).unwrap_err();
    let line = err.to_string();
    for held in ["density", "shadow", "velocity", "obstacles"] {
        assert!(
            line.contains(held),
            "the refusal must list the grids: {line}"
        );
    }
}

#[test]
fn truncated_and_foreign_files_are_refused_in_one_line() {
    let bytes = data(TWO_GRIDS);
    for length in [0, 7, 40, 200, bytes.len() / 2, bytes.len() - 1] {
        let err = vdb::list_grids(&bytes[..length])
            .and_then(|_| vdb::read_float_grid(&bytes[..length], "density", &Limits::default()))
            .unwrap_err();
        let line = err.to_string();
        assert!(!line.contains('\n'), "{line}");
    }
    let err = vdb::list_grids(b"ply\nformat ascii 1.0\n").unwrap_err();
    assert_eq!(err, VdbError::NotVdb);
    // A dense limit below the grid's size is refused before anything is allocated.
    let tight = Limits {
        max_dense_voxels: 1000,
    };
    let err = vdb::read_float_grid(&data(SMOKE), "density", &tight).unwrap_err();
    assert!(err.to_string().contains("limit"), "{err}");
}

#[test]
fn a_grid_with_a_background_density_is_not_a_medium() {
    let mut grid = vdb::read_float_grid(&data(TWO_GRIDS), "heat", &Limits::default()).unwrap();
    grid.background = 0.25;
    let err = DensityGrid::from_vdb(&grid, DAffine3::IDENTITY, 1.0).unwrap_err();
    assert!(matches!(err, GridError::Background { .. }), "{err}");
    grid.background = 0.0;
    grid.values[7] = -1.0;
    let err = DensityGrid::from_vdb(&grid, DAffine3::IDENTITY, 1.0).unwrap_err();
    assert!(matches!(err, GridError::Negative { .. }), "{err}");
}

#[test]
fn the_real_smoke_marched_on_the_gpu_agrees_with_the_mirror_and_converges() {
    let grid = vdb::read_float_grid(&data(SMOKE), "density", &Limits::default()).unwrap();
    // Placed 2 m up, density 1 -> 4 extinction per metre: optical depths of a few across it.
    let world_from_file = DAffine3::from_translation(DVec3::new(0.0, 2.0, 0.0));
    let medium = DensityGrid::from_vdb(&grid, world_from_file, 4.0).unwrap();
    let (lo, hi) = medium.world_bounds().unwrap();
    let centre = 0.5 * (lo + hi);
    let light = (centre + DVec3::new(3.0, 12.0, 2.0)).as_vec3();
    // Points through the smoke's box, on a line from corner to corner and beyond.
    let points: Vec<Vec3> = (0..64)
        .map(|i| (lo + (hi - lo) * (-0.1 + 1.2 * f64::from(i) / 63.0)).as_vec3())
        .collect();
    let gpu = common::gpu();
    let mut ledger = MemoryLedger::for_device(&gpu.limits);
    let uploaded = GpuGrid::upload(&gpu, &mut ledger, &medium).unwrap();
    // The voxels and the 160-byte uniform (the placement, the frame's march settings and a
    // shape's closed form).
    assert_eq!(uploaded.bytes, 51 * 49 * 96 * 4 + 160);
    let march = GridMarch::new(&gpu);
    let (n, n2) = (1024, 2048);
    let t_n = march
        .transmittance(&gpu, &uploaded, light, &points, n)
        .wait()
        .unwrap();
    let t_2n = march
        .transmittance(&gpu, &uploaded, light, &points, n2)
        .wait()
        .unwrap();
    let mut shadowed = 0;
    for (i, p) in points.iter().enumerate() {
        let cpu = (-medium.marched_optical_depth(light.as_dvec3(), p.as_dvec3(), n)).exp();
        assert!(
            (f64::from(t_n[i]) - cpu).abs() < 1e-4,
            "{p}: GPU {}, CPU {cpu}",
            t_n[i]
        );
        // Converged: N and 2N steps within the reference's 1e-4.
        assert!(
            (t_n[i] - t_2n[i]).abs() < 1e-4,
            "{p}: {} vs {}",
            t_n[i],
            t_2n[i]
        );
        shadowed += usize::from(cpu < 0.5);
    }
    assert!(
        shadowed >= 8,
        "the smoke must shadow part of the line ({shadowed} points)"
    );
}

#[test]
fn info_describes_a_vdb_file_and_refuses_a_broken_one_in_one_line() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/volumes");
    let smoke = dir.join(SMOKE);
    let out = common::smokeshadow(&["info", smoke.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    for needle in [
        "1 grid(s)",
        "\"density\": float",
        "blosc",
        "90197 active voxels",
        "51x49x96",
    ] {
        assert!(text.contains(needle), "no {needle:?} in:\n{text}");
    }
    let empty = dir.join(EMPTY);
    let out = common::smokeshadow(&["info", empty.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(
        text.contains("an empty medium") && text.contains("only float grids are"),
        "{text}"
    );
    // Half a file: one line naming the file and the problem, exit 2.
    let scratch = common::scratch("vdb_info");
    let half = scratch.join("half.vdb");
    let bytes = data(TWO_GRIDS);
    std::fs::write(&half, &bytes[..bytes.len() / 2]).unwrap();
    let out = common::smokeshadow(&["info", half.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let lines = common::error_lines(&out);
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(
        lines[0].starts_with("error: ") && lines[0].contains("half.vdb"),
        "{lines:?}"
    );
}

#[test]
fn bench_volume_measures_every_stage_of_a_file_and_of_the_cloud() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/volumes");
    let out = common::scratch("bench_volume");
    let smoke = dir.join(TWO_GRIDS);
    for (source, expected_rows) in [
        (smoke.to_str().unwrap(), 2 * 2),
        ("cloud", 1 + 2 * 2 + 2 * 2 * 2 * 2),
    ] {
        let o = out.join(if source == "cloud" { "cloud" } else { "file" });
        let args = [
            "bench",
            "--volume",
            source,
            "--grid-sizes",
            "8,16",
            "--light-steps",
            "2,4",
            "--coverages",
            "0.3,0.9",
            "--eye-steps",
            "4",
            "--frames",
            "1",
            "--warmup",
            "0",
            "--size",
            "16x12",
            "-o",
            o.to_str().unwrap(),
        ];
        let run = common::smokeshadow(&args);
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let csv = std::fs::read_to_string(o.join("bench_volume.csv")).unwrap();
        let rows: Vec<&str> = csv.lines().skip(1).collect();
        assert_eq!(rows.len(), expected_rows, "{csv}");
        for row in rows {
            // (No field holds a comma: the stages are named without.)
            let fields: Vec<&str> = row.split(',').collect();
            assert_eq!(fields.len(), 8, "{row}");
            let ms: f64 = fields[6].parse().unwrap();
            assert!(ms > 0.0 && ms.is_finite(), "{row}");
            // The eye march's error against the most light steps: 0 for those, positive or
            // empty (the other stages) otherwise.
            if fields[3].starts_with("eye march") {
                let rmse: f64 = fields[7].parse().unwrap();
                assert_eq!(rmse == 0.0, fields[5] == "4", "{row}");
            } else {
                assert_eq!(fields[7], "", "{row}");
            }
        }
        // The sun-step chart: the eye march's time and error over the two light step counts.
        let chart = std::fs::read_to_string(o.join("bench_volume_light_steps.svg")).unwrap();
        assert!(
            chart.starts_with("<svg") && chart.contains("eye march ms"),
            "{chart}"
        );
    }
}

#[test]
fn the_frame_study_refuses_srm_light_steps_out_of_range_before_rendering() {
    let out = common::scratch("bench_volume_bad_light_steps");
    let run = common::smokeshadow(&[
        "bench",
        "--volume",
        "cloud",
        "-t",
        "srm",
        "--light-steps",
        "8,5000",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(2));
    // (common::error_lines: the Vulkan loader may print a warning of its own.)
    let lines = common::error_lines(&run);
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(
        lines[0].starts_with("error: ") && lines[0].contains("srm_light_steps = 5000"),
        "{lines:?}"
    );
    assert!(
        !out.join("bench_volume_frames.csv").exists(),
        "nothing written"
    );
}
