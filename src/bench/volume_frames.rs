//! `smokeshadow bench --volume cloud|FILE.vdb -t esm,bsm,fom,srm`: whole frames of a density
//! volume's scene per technique (and, for the cloud, per coverage), timed on the GPU by the
//! frame's timestamp queries: the dissertation's coverage experiment (000 §4.1.5), where SRM's
//! cost grows with the cloud the eye crosses and a map's does not. Each frame's time, its
//! build ("shadow") and the eye's march ("volume"), and its RMS transmittance error against
//! `exact` at the frame's shaded points (the volume's eye samples and the lit ground); every
//! technique's time is also given as a ratio to `srm`'s at the same coverage, and for each map
//! the coverage from which `srm` is the slower: ratios within one run, as the issue asks, not
//! milliseconds to compare across machines. Two more of the dissertation's axes: the maps'
//! resolution (its generation against total time at 256², 512² and 1024²) and the build's
//! samples along each texel's ray (its 10-300); `srm`, which has neither, is measured per count
//! of its light samples instead (its 1-50), and the ratios are to the first count given.

use crate::Wait;
use std::path::{Path, PathBuf};

use anyhow::Context;

use smokeshadow_core::gpu::Gpu;
use smokeshadow_core::medium::grid::DensityGrid;
use smokeshadow_core::render::{
    OUTPUT_FORMAT, OffscreenTarget, RenderOptions, Renderer, TechniqueConfig,
};
use smokeshadow_core::scene::Scene;

/// The file the rows go to, in the bench's output folder.
pub const CSV_FILE: &str = "bench_volume_frames.csv";

/// What the frame study renders.
#[derive(Clone, Debug)]
pub struct FrameStudy {
    /// The scene: the embedded cloud, or a bare VDB file's.
    pub scene: Scene,
    /// The cloud's coverages (`None`: the scene as it is).
    pub coverages: Vec<Option<f32>>,
    pub techniques: Vec<String>,
    pub channels: u32,
    /// The maps' resolutions and the build's steps along each texel's ray.
    pub shadow_res: Vec<u32>,
    pub build_steps: Vec<u32>,
    /// `srm`'s light samples per lookup (`srm_light_steps`), each a row of its own.
    pub light_steps: Vec<u32>,
    pub frames: u32,
    pub warmup: u32,
}

/// One technique at one coverage.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameRow {
    pub coverage: Option<f32>,
    pub technique: String,
    pub shadow_res: u32,
    pub build_steps: u32,
    /// `srm`'s light samples per lookup (`None` for a map).
    pub light_steps: Option<u32>,
    /// Median GPU time of the whole frame, of its build and of the eye's march, ms.
    pub frame_ms: f64,
    pub build_ms: f64,
    pub eye_ms: f64,
    /// Bytes of the technique's maps.
    pub bytes: u64,
    /// RMS of T - T_exact over the frame's shaded points.
    pub rms_t: f64,
    /// Mean of T - T_exact over the volume's eye samples at its thin edges (extinction below a
    /// quarter of the samples' 90th percentile) and inside it (above), NaN where there are none:
    /// positive is brighter than the reference (the dissertation's "ESM and BSM brighter at
    /// cloud edges", "BSM darker"), as numbers.
    pub bias_edge: f64,
    pub bias_inside: f64,
}

/// Which of `points` are the volume's thin edges (`Some(true)`), its inside (`Some(false)`), or
/// not in it (`None`): extinction below a quarter of the 90th percentile of the points' non-zero
/// extinctions is an edge.
pub fn edge_classes(grid: &DensityGrid, points: &[glam::Vec3]) -> Vec<Option<bool>> {
    let sigma: Vec<f64> = points
        .iter()
        .map(|p| grid.extinction_at(p.as_dvec3()))
        .collect();
    let mut inside: Vec<f64> = sigma.iter().copied().filter(|&s| s > 0.0).collect();
    inside.sort_by(f64::total_cmp);
    let Some(&p90) = inside.get(inside.len() * 9 / 10) else {
        return vec![None; points.len()];
    };
    sigma
        .iter()
        .map(|&s| (s > 0.0).then_some(s < 0.25 * p90))
        .collect()
}

/// Mean of `t - exact` over the points whose class is `class`.
fn mean_bias(t: &[f32], exact: &[f32], classes: &[Option<bool>], class: bool) -> f64 {
    let (sum, n) = t
        .iter()
        .zip(exact)
        .zip(classes)
        .filter(|(_, c)| **c == Some(class))
        .fold((0.0, 0u32), |(s, n), ((&a, &b), _)| {
            (s + f64::from(a) - f64::from(b), n + 1)
        });
    if n == 0 { f64::NAN } else { sum / f64::from(n) }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// Renders the study's frames; a technique that cannot shadow the scene is refused in one line.
pub fn run(gpu: &Gpu, study: &FrameStudy) -> anyhow::Result<Vec<FrameRow>> {
    if !gpu.has_timestamps() {
        anyhow::bail!(
            "the volume frame study times frames with GPU timestamp queries, which {} does not have",
            gpu.info.name
        );
    }
    let (w, h) = (study.scene.output.width_px, study.scene.output.height_px);
    let first = TechniqueConfig {
        name: study.techniques[0].clone(),
        params: study.scene.shadow.params(study.channels),
    };
    let mut renderer = Renderer::new(gpu, w, h, OUTPUT_FORMAT, &first).wait()?;
    let target = OffscreenTarget::new(gpu, w, h);
    let options = RenderOptions::default();
    let mut rows = Vec::new();
    for &coverage in &study.coverages {
        let mut base = study.scene.clone();
        if let (Some(c), Some(volume)) = (coverage, base.volume.as_mut()) {
            volume.cloud.coverage = c;
        }
        // exact's T at the shaded points, once per coverage (the build's steps do not change
        // it; its check against the f64 mirror runs as every command's does).
        renderer
            .set_technique(
                gpu,
                &TechniqueConfig {
                    name: smokeshadow_core::shadow::reference().name.to_owned(),
                    params: base.shadow.params(1),
                },
            )
            .wait()?;
        renderer
            .render(gpu, &base, &[], &options, &target.view)
            .wait()?;
        smokeshadow_core::render::reference_check::verify(&mut renderer, gpu, &base, &[]).wait()?;
        let points = smokeshadow_core::render::shaded::shaded_points(
            &base,
            &[],
            (w, h),
            smokeshadow_core::render::shaded::SHADED_STRIDE_PX,
            renderer.medium().grid().map(|g| &**g),
        );
        let exact = renderer.probe(gpu, &base, &[], &points).wait()?;
        let classes = match renderer.medium().grid() {
            Some(grid) => edge_classes(grid, &points),
            None => vec![None; points.len()],
        };
        let mut cells = Vec::new();
        for name in &study.techniques {
            // `srm` has no map: once per count of its light samples instead.
            if name == smokeshadow_core::shadow::srm::ENTRY.name {
                for &light in &study.light_steps {
                    cells.push((
                        name.clone(),
                        study.shadow_res[0],
                        study.build_steps[0],
                        Some(light),
                    ));
                }
                continue;
            }
            for &res in &study.shadow_res {
                for &steps in &study.build_steps {
                    cells.push((name.clone(), res, steps, None));
                }
            }
        }
        for (name, res, steps, light_steps) in cells {
            let mut scene = base.clone();
            scene.shadow.resolution_px = res;
            if let Some(volume) = scene.volume.as_mut() {
                volume.build_steps = steps;
            }
            let mut params = scene.shadow.params(study.channels);
            if let Some(light) = light_steps {
                smokeshadow_core::shadow::set_param(
                    &mut params,
                    smokeshadow_core::shadow::srm::LIGHT_STEPS.key,
                    &(light as f32).into(),
                )?;
            }
            renderer
                .set_technique(
                    gpu,
                    &TechniqueConfig {
                        name: name.clone(),
                        params,
                    },
                )
                .wait()?;
            let (mut frame, mut build, mut eye) = (Vec::new(), Vec::new(), Vec::new());
            for i in 0..study.warmup + study.frames {
                let stats = renderer
                    .render(gpu, &scene, &[], &options, &target.view)
                    .wait()?;
                let times = renderer.gpu_times(gpu).wait()?;
                if i >= study.warmup {
                    frame.push(stats.frame_ms(&times));
                    build.push(times.get("shadow").unwrap_or(0.0));
                    eye.push(
                        times
                            .get(smokeshadow_core::medium::eye_pass::PASS_NAME)
                            .unwrap_or(0.0),
                    );
                }
            }
            let t = renderer.probe(gpu, &scene, &[], &points).wait()?;
            rows.push(FrameRow {
                coverage,
                technique: name.clone(),
                shadow_res: res,
                build_steps: steps,
                light_steps,
                frame_ms: median(frame),
                build_ms: median(build),
                eye_ms: median(eye),
                bytes: renderer.shadow_bytes().0,
                rms_t: smokeshadow_core::render::shaded::rms_difference(&t, &exact),
                bias_edge: mean_bias(&t, &exact, &classes, true),
                bias_inside: mean_bias(&t, &exact, &classes, false),
            });
        }
    }
    Ok(rows)
}

/// `row`'s frame time over `srm`'s at the same coverage (its first count of light samples),
/// when the run has `srm`.
pub fn ratio_to_srm(rows: &[FrameRow], row: &FrameRow) -> Option<f64> {
    rows.iter()
        .find(|r| {
            r.technique == smokeshadow_core::shadow::srm::ENTRY.name && r.coverage == row.coverage
        })
        .map(|srm| row.frame_ms / srm.frame_ms)
}

/// For each map technique, the first coverage at which `srm`'s frame is slower than the map's
/// (in the order the coverages were given), or `None` when it never is; at the first
/// resolution and build step count measured.
pub fn srm_crossovers(rows: &[FrameRow]) -> Vec<(String, Option<f32>)> {
    let Some(first) = rows.first() else {
        return Vec::new();
    };
    let (res, steps) = (first.shadow_res, first.build_steps);
    let mut names: Vec<&str> = Vec::new();
    for r in rows {
        if r.technique != "srm" && !names.contains(&r.technique.as_str()) {
            names.push(&r.technique);
        }
    }
    names
        .into_iter()
        .map(|name| {
            let first = rows
                .iter()
                .filter(|r| r.technique == name && r.shadow_res == res && r.build_steps == steps)
                .find(|r| ratio_to_srm(rows, r).is_some_and(|ratio| ratio < 1.0))
                .and_then(|r| r.coverage);
            (name.to_owned(), first)
        })
        .collect()
}

/// The charts' files, in the bench's output folder: each technique's frame over `srm`'s against
/// the coverage (with more than one coverage), and each configuration's RMS T error against its
/// frame time (every run).
pub const RATIO_CHART: &str = "bench_volume_frames_over_srm.svg";
pub const ERROR_CHART: &str = "bench_volume_frames_error.svg";

/// The study's charts as SVG documents: (file name, document).
pub fn charts(rows: &[FrameRow]) -> anyhow::Result<Vec<(&'static str, String)>> {
    use crate::sweep::charts::{LogLogSeries, log_log_svg};
    let mut names: Vec<&str> = Vec::new();
    for r in rows {
        if !names.contains(&r.technique.as_str()) {
            names.push(&r.technique);
        }
    }
    let label = |r: &FrameRow| match r.light_steps {
        Some(n) => format!("{} ({n} light samples)", r.technique),
        None => format!(
            "{} ({}², {} build steps)",
            r.technique, r.shadow_res, r.build_steps
        ),
    };
    let mut out = Vec::new();
    let mut coverages: Vec<f32> = rows.iter().filter_map(|r| r.coverage).collect();
    coverages.dedup();
    if coverages.len() > 1 {
        // One line per technique and configuration, over the coverages.
        let mut series: Vec<LogLogSeries> = Vec::new();
        for r in rows
            .iter()
            .filter(|r| r.technique != smokeshadow_core::shadow::srm::ENTRY.name)
        {
            let (Some(c), Some(ratio)) = (r.coverage, ratio_to_srm(rows, r)) else {
                continue;
            };
            LogLogSeries::push_point(&mut series, label(r), (f64::from(c), ratio));
        }
        out.push((
            RATIO_CHART,
            log_log_svg(
                "Frame time over srm's against cloud coverage (below 1: the map is faster)",
                "coverage (log scale)",
                "frame time / srm's (log scale)",
                &series,
            )?,
        ));
    }
    let series: Vec<LogLogSeries> = names
        .iter()
        .map(|&name| LogLogSeries {
            label: name.to_owned(),
            points: rows
                .iter()
                .filter(|r| r.technique == name)
                .map(|r| (r.frame_ms, r.rms_t))
                .collect(),
        })
        .collect();
    out.push((
        ERROR_CHART,
        log_log_svg(
            "RMS error of T against exact, against the frame's GPU time (each configuration)",
            "frame ms (log scale)",
            "RMS T error (log scale)",
            &series,
        )?,
    ));
    Ok(out)
}

/// Writes the study's charts into `folder` (created if missing), atomically; returns their paths.
pub fn write_charts(rows: &[FrameRow], folder: &Path) -> anyhow::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(folder)
        .with_context(|| format!("cannot create {}", folder.display()))?;
    charts(rows)?
        .into_iter()
        .map(|(name, svg)| {
            let path = folder.join(name);
            crate::output::write_atomic(&path, svg.as_bytes())?;
            Ok(path)
        })
        .collect()
}

/// Writes the rows as CSV into `folder` (created if missing), atomically.
pub fn write_csv(rows: &[FrameRow], folder: &Path) -> anyhow::Result<PathBuf> {
    std::fs::create_dir_all(folder)
        .with_context(|| format!("cannot create {}", folder.display()))?;
    let mut csv = csv::Writer::from_writer(Vec::new());
    csv.write_record([
        "coverage",
        "technique",
        "shadow_res",
        "build_steps",
        "srm_light_steps",
        "bytes",
        "frame_gpu_ms",
        "build_gpu_ms",
        "eye_gpu_ms",
        "frame_over_srm",
        "rms_t_vs_exact",
        "bias_t_edge",
        "bias_t_inside",
    ])?;
    for r in rows {
        csv.write_record([
            r.coverage.map_or(String::new(), |c| c.to_string()),
            r.technique.clone(),
            r.shadow_res.to_string(),
            r.build_steps.to_string(),
            r.light_steps.map_or(String::new(), |n| n.to_string()),
            r.bytes.to_string(),
            format!("{:.3}", r.frame_ms),
            format!("{:.3}", r.build_ms),
            format!("{:.3}", r.eye_ms),
            ratio_to_srm(rows, r).map_or(String::new(), |x| format!("{x:.4}")),
            format!("{:.6}", r.rms_t),
            format!("{:.6}", r.bias_edge),
            format!("{:.6}", r.bias_inside),
        ])?;
    }
    let bytes = csv.into_inner().context("writing the CSV")?;
    let path = folder.join(CSV_FILE);
    crate::output::write_atomic(&path, &bytes)?;
    Ok(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(coverage: f32, technique: &str, frame_ms: f64) -> FrameRow {
        FrameRow {
            coverage: Some(coverage),
            technique: technique.to_owned(),
            shadow_res: 512,
            build_steps: 64,
            light_steps: (technique == "srm").then_some(16),
            frame_ms,
            build_ms: 0.0,
            eye_ms: 0.0,
            bytes: 0,
            rms_t: 0.01,
            bias_edge: 0.0,
            bias_inside: 0.0,
        }
    }

    #[test]
    fn thin_edges_are_below_a_quarter_of_the_dense_samples_and_bias_is_signed() {
        use smokeshadow_core::medium::analytic::{HomogeneousMedium, Shape};
        // A ball of 1/m whose voxels the trilinear ramp thins at its rim.
        let ball = HomogeneousMedium {
            shape: Shape::Sphere {
                center: glam::DVec3::splat(1.0),
                radius_m: 0.8,
            },
            extinction_per_m: 1.0,
        };
        let mut grid = DensityGrid::voxelize(
            &ball,
            glam::DVec3::ZERO,
            glam::DVec3::splat(2.0),
            glam::UVec3::splat(8),
        );
        grid.analytic = None;
        let points: Vec<glam::Vec3> = [1.0, 1.84, 1.3, 3.0]
            .map(|x| glam::Vec3::new(x, 1.0, 1.0))
            .to_vec();
        let classes = edge_classes(&grid, &points);
        assert_eq!(classes[0], Some(false), "the centre is inside");
        assert_eq!(classes[3], None, "outside the ball");
        assert_eq!(
            classes[1],
            Some(true),
            "{classes:?}: the rim's ramp is an edge"
        );
        let t = [0.5, 0.9, 0.6, 1.0];
        let exact = [0.4, 0.7, 0.6, 1.0];
        assert!((mean_bias(&t, &exact, &classes, true) - 0.2).abs() < 1e-6);
        assert!((mean_bias(&t, &exact, &classes, false) - 0.05).abs() < 1e-6);
    }

    #[test]
    fn the_crossover_is_the_first_coverage_where_srm_is_slower() {
        let rows = vec![
            row(0.1, "srm", 10.0),
            row(0.1, "esm", 12.0),
            row(0.1, "fom", 30.0),
            row(0.5, "srm", 20.0),
            row(0.5, "esm", 15.0),
            row(0.5, "fom", 30.0),
        ];
        assert_eq!(ratio_to_srm(&rows, &rows[1]), Some(1.2));
        // The charts: the ratio over the coverages for each map, and every row's error.
        let charts = charts(&rows).unwrap();
        assert_eq!(
            charts.iter().map(|(n, _)| *n).collect::<Vec<_>>(),
            vec![RATIO_CHART, ERROR_CHART]
        );
        assert!(charts[0].1.contains("esm (512²") && !charts[0].1.contains(">srm"));
        assert!(charts[1].1.contains("fom") && charts[1].1.contains("srm"));
        assert_eq!(
            srm_crossovers(&rows),
            vec![("esm".to_owned(), Some(0.5)), ("fom".to_owned(), None)]
        );
    }
}
