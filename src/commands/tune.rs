//! `smokeshadow tune`: chooses every technique's parameters by one procedure on training scenes
//! (`crate::tune`), checks them on held-out scenes, and writes a parameter file that
//! `--params FILE` reads.

use crate::Wait;
use std::collections::BTreeMap;
use std::path::PathBuf;

use crate::tune::{Case, TuneOptions, TuneRecord};
use smokeshadow_core::gpu::{AdapterPreference, Gpu};
use smokeshadow_core::scene::Scene;
use smokeshadow_core::shadow;

#[derive(Clone, Debug, clap::Args)]
pub struct TuneArgs {
    /// Training scenes, comma-separated names or paths (default: the training set,
    /// `scene::TRAINING`). The thesis and gallery scenes, where the answers are given, are
    /// refused.
    #[arg(long, value_delimiter = ',', value_name = "LIST")]
    pub scenes: Option<Vec<String>>,
    /// Held-out scenes the chosen values are checked on, or `none` (default: thesis_plume).
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "LIST|none",
        default_value = "thesis_plume"
    )]
    pub held_out: Vec<String>,
    /// Techniques, comma-separated, or `all` (default: every contender with parameters).
    #[arg(long, value_delimiter = ',')]
    pub techniques: Option<Vec<String>>,
    /// Byte budgets per texel each candidate runs at (its largest configuration within each).
    #[arg(long, value_delimiter = ',', default_value = "48,24,12",
          value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub bytes_per_texel: Vec<u32>,
    /// Memory budgets in total bytes (as `sweep --memory` takes them: `12MiB,6MiB,3MiB`), or
    /// `none`: for each, every technique's map resolution is chosen among `--shape-res` on the
    /// training scenes (its largest configuration that fits the budget there, its chosen
    /// parameters), and written as `[shapes]`; a sweep's answer at equal total memory takes
    /// each technique at that resolution.
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "SIZE,...|none",
        default_value = "12MiB,6MiB,3MiB"
    )]
    pub memory: Vec<String>,
    /// The map resolutions the shapes are chosen among.
    #[arg(long, value_delimiter = ',', default_value = "256,512,1024",
          value_parser = clap::value_parser!(u32).range(1..=8192))]
    pub shape_res: Vec<u32>,
    /// Candidates scored per technique, the starting values included.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub evaluations: u32,
    /// Seed of each technique's candidate generator (the same for every technique).
    #[arg(long, default_value_t = 2026)]
    pub seed: u64,
    /// Output size of every scene as WIDTHxHEIGHT (default: each scene's).
    #[arg(long)]
    pub size: Option<super::Size>,
    /// Starting values: `--params FILE|paper` and `--param KEY=VALUE` (default: the registry's).
    #[command(flatten)]
    pub params: super::ParamArgs,
    /// The parameter file to write.
    #[arg(long, short = 'o', default_value = "tuned_params.toml")]
    pub output: PathBuf,
}

fn load(names: &[String], args: &TuneArgs) -> anyhow::Result<Vec<Scene>> {
    names
        .iter()
        .map(|name| {
            let mut scene =
                super::load_scene(Some(std::path::Path::new(name)), Default::default())?;
            if let Some(size) = args.size {
                scene.output.width_px = size.width;
                scene.output.height_px = size.height;
            }
            Ok(scene)
        })
        .collect()
}

pub fn run(args: &TuneArgs, adapter: &AdapterPreference) -> anyhow::Result<()> {
    let training_names: Vec<String> = match &args.scenes {
        Some(list) => list.clone(),
        None => smokeshadow_core::scene::TRAINING
            .iter()
            .map(|s| s.to_string())
            .collect(),
    };
    if training_names.is_empty() {
        anyhow::bail!("--scenes is empty: give training scenes");
    }
    for name in &training_names {
        if smokeshadow_core::scene::GALLERY.contains(&name.as_str())
            || smokeshadow_core::scene::BASELINE_SCENES.contains(&name.as_str())
        {
            anyhow::bail!(
                "--scenes {name}: the thesis and gallery scenes are where the answers are given; \
                 tune on other scenes (default: {})",
                smokeshadow_core::scene::TRAINING.join(", ")
            );
        }
    }
    let held_names: Vec<String> = match args.held_out.as_slice() {
        [n] if n == "none" => Vec::new(),
        list => list.to_vec(),
    };
    for name in training_names.iter().chain(&held_names) {
        if smokeshadow_core::scene::HOLDOUT.contains(&name.as_str()) {
            anyhow::bail!(
                "{name} is held out from tuning ({}): the convergence tests check the chosen \
                 values on smoke no parameter was chosen for",
                smokeshadow_core::scene::HOLDOUT.join(", ")
            );
        }
    }
    let entries: Vec<&'static shadow::TechniqueEntry> = match &args.techniques {
        None => shadow::contenders()
            .filter(|e| !crate::tune::free_params(e).is_empty())
            .collect(),
        Some(list) => shadow::expand_all(list)
            .iter()
            .map(|n| {
                let e = shadow::find(n)?;
                if e.role != shadow::Role::Contender {
                    anyhow::bail!("--techniques {n}: only contenders are tuned");
                }
                Ok(e)
            })
            .collect::<anyhow::Result<_>>()?,
    };
    let memory: Vec<u64> = match args.memory.as_slice() {
        [n] if n == "none" => Vec::new(),
        list => list
            .iter()
            .map(|s| {
                smokeshadow_core::sweep::plan::parse_memory(s)
                    .map_err(|e| anyhow::anyhow!("--memory {e}"))
            })
            .collect::<anyhow::Result<_>>()?,
    };
    if args.shape_res.is_empty() && !memory.is_empty() {
        anyhow::bail!("--shape-res is empty: give the map resolutions to choose among");
    }
    // The techniques whose shapes are chosen: those named, or every contender that shadows the
    // training scenes' particles (with parameters or not: a resolution is every technique's).
    let shape_entries: Vec<&'static shadow::TechniqueEntry> = match &args.techniques {
        Some(_) => entries.clone(),
        None => shadow::contenders()
            .filter(|e| e.shadows_particles)
            .collect(),
    };
    let mut starting = shadow::TechniqueParams::new(8, 512);
    for (key, value) in args.params.all() {
        shadow::set_param(&mut starting, key, value)?;
    }
    let gpu = Gpu::new(adapter).wait()?;
    let case = |scene: Scene| -> anyhow::Result<Case> {
        let name = scene.name.clone();
        eprintln!("{name}: exact reference and its self-check");
        Case::new(&gpu, scene).map_err(|e| anyhow::anyhow!("{name}: {e:#}"))
    };
    let mut training: Vec<Case> = load(&training_names, args)?
        .into_iter()
        .map(case)
        .collect::<anyhow::Result<_>>()?;
    let mut held_out: Vec<Case> = load(&held_names, args)?
        .into_iter()
        .map(case)
        .collect::<anyhow::Result<_>>()?;
    let options = TuneOptions {
        bytes_per_texel: args.bytes_per_texel.clone(),
        evaluations: args.evaluations,
        seed: args.seed,
    };
    let start = std::time::Instant::now();
    let mut tuned = Vec::new();
    for entry in entries {
        let mut report = |k: u32,
                          values: &BTreeMap<String, shadow::ParamValue>,
                          score: Option<f64>| {
            eprintln!(
                "{} {k}/{}: {} -> {}",
                entry.name,
                options.evaluations,
                values
                    .iter()
                    .map(|(k, v)| format!("{k}={}", value_text(v)))
                    .collect::<Vec<_>>()
                    .join(" "),
                score.map_or(
                    "out (fits no budget, or unstable under the reversed draw order)".to_owned(),
                    |s| format!("{s:.5}")
                )
            );
        };
        let t = crate::tune::tune_technique(
            &gpu,
            entry,
            &starting,
            &mut training,
            &mut held_out,
            &options,
            &mut report,
        )?;
        println!(
            "{:<10} {:>3} evaluations: training RMS T {:.5} -> {:.5}{}; {}",
            t.technique,
            t.evaluations,
            t.start_training,
            t.chosen_training,
            match (t.start_held_out, t.chosen_held_out) {
                (Some(a), Some(b)) => format!(", held out {a:.5} -> {b:.5}"),
                (Some(a), None) => format!(", held out {a:.5} -> out"),
                _ => String::new(),
            },
            t.chosen
                .iter()
                .map(|(k, v)| format!("{k} = {}", value_text(v)))
                .collect::<Vec<_>>()
                .join(", ")
        );
        tuned.push(t);
    }
    let mut shapes = Vec::new();
    for entry in shape_entries {
        let values = tuned
            .iter()
            .find(|t| t.technique == entry.name)
            .map(|t| t.chosen.clone())
            .unwrap_or_default();
        let mut report = |total: u64, res: u32, score: Option<f64>| {
            eprintln!(
                "{} shape at {}: {res}² -> {}",
                entry.name,
                crate::report::bytes(total),
                score.map_or("fits no configuration".to_owned(), |s| format!("{s:.5}"))
            );
        };
        let chosen = crate::tune::choose_shapes(
            &gpu,
            &mut training,
            entry,
            &values,
            &memory,
            &args.shape_res,
            &mut report,
        )?;
        if !chosen.is_empty() {
            println!(
                "{:<10} shapes: {}",
                entry.name,
                chosen
                    .iter()
                    .rev()
                    .map(|(total, s)| format!(
                        "{}² at {} ({:.5})",
                        s.resolution,
                        crate::report::bytes(*total),
                        s.training
                    ))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
        shapes.push((entry.name, chosen));
    }
    let command = std::iter::once("smokeshadow".to_owned())
        .chain(std::env::args().skip(1))
        .collect::<Vec<_>>()
        .join(" ");
    let record = TuneRecord {
        command,
        training: training.iter().map(|c| c.scene.name.clone()).collect(),
        held_out: held_out.iter().map(|c| c.scene.name.clone()).collect(),
        bytes_per_texel: options.bytes_per_texel.clone(),
        evaluations: options.evaluations,
        seed: options.seed,
        memory: memory.clone(),
        shape_resolutions: match memory.is_empty() {
            true => Vec::new(),
            false => args.shape_res.clone(),
        },
        adapter: gpu.describe(),
        tool_version: env!("CARGO_PKG_VERSION").to_owned(),
        techniques: BTreeMap::new(),
    };
    crate::tune::write_params_file(&args.output, record, &tuned, &shapes)?;
    println!(
        "{} techniques tuned in {:.0} s; parameters: {} (read it with --params {})",
        tuned.len(),
        start.elapsed().as_secs_f64(),
        args.output.display(),
        args.output.display()
    );
    Ok(())
}

fn value_text(v: &shadow::ParamValue) -> String {
    match v {
        shadow::ParamValue::Number(x) => x.to_string(),
        shadow::ParamValue::Choice(c) => format!("\"{c}\""),
    }
}
