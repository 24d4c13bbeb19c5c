//! The study behind the defaults of `msm`'s and `tmsm`'s bias β and overestimation η: the RMS
//! transmittance error against `exact` over a scene's shaded points (the sweep's
//! `rms_transmittance_error`) for each family, budget, β and η, on the CPU adapter.
//!
//! `cargo run --release --example moment_params [SCENE.toml|""] [point|segment]`

use smokeshadow::Wait;
use smokeshadow::gpu::{AdapterPreference, Gpu};
use smokeshadow::render::shaded::{rms_difference, shaded_points};
use smokeshadow::render::{OUTPUT_FORMAT, Renderer, TechniqueConfig};
use smokeshadow::scene::Scene;
use smokeshadow::shadow::{SplatMode, TechniqueParams, set_param};
use smokeshadow::sim::simulate;

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let scene = match args.next() {
        Some(path) if !path.is_empty() => Scene::load(
            std::path::Path::new(&path),
            &smokeshadow::files::Files::host(),
        )?,
        _ => Scene::thesis_plume(),
    };
    let splat = match args.next().as_deref() {
        Some("segment") => SplatMode::Segment,
        _ => SplatMode::Point,
    };
    let gpu = Gpu::new(&AdapterPreference::Cpu).wait()?;
    let particles = simulate(&scene);
    let (w, h) = (scene.output.width_px / 2, scene.output.height_px / 2);
    let points = shaded_points(&scene, &particles, (w, h), 4, None);
    let res = scene.shadow.resolution_px;
    let config = |name: &str, channels: u32, values: &[(String, f32)]| -> anyhow::Result<_> {
        let mut params = TechniqueParams {
            splat,
            ..TechniqueParams::new(channels, res)
        };
        for (key, value) in values {
            set_param(&mut params, key, &(*value).into())?;
        }
        Ok(TechniqueConfig {
            name: name.to_owned(),
            params,
        })
    };
    let mut renderer =
        Renderer::new(&gpu, w, h, OUTPUT_FORMAT, &config("exact", 1, &[])?).wait()?;
    let exact = renderer.probe(&gpu, &scene, &particles, &points).wait()?;
    println!(
        "RMS T error against exact over {} shaded points, {} splats, {res}² maps",
        points.len(),
        splat.name()
    );
    println!("technique channels bias overestimation rms");
    for name in ["msm", "tmsm"] {
        for channels in [5, 7, 9] {
            for bias in [5e-6f32, 5e-5, 5e-4, 5e-3] {
                for eta in [0.0f32, 0.25, 0.4, 0.5, 0.6, 0.75, 1.0] {
                    let values = [
                        (format!("{name}_bias"), bias),
                        (format!("{name}_overestimation"), eta),
                    ];
                    renderer
                        .set_technique(&gpu, &config(name, channels, &values)?)
                        .wait()?;
                    let t = renderer.probe(&gpu, &scene, &particles, &points).wait()?;
                    let broken = t.iter().filter(|v| !v.is_finite()).count();
                    println!(
                        "{name} {channels} {bias:e} {eta} {:.5}{}",
                        rms_difference(&t, &exact),
                        if broken > 0 {
                            format!(" ({broken} not finite)")
                        } else {
                            String::new()
                        }
                    );
                }
            }
        }
    }
    Ok(())
}
