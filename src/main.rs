//! The `smokeshadow` command line: parses arguments and dispatches to `smokeshadow::commands`.

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use smokeshadow::commands;
use smokeshadow::gpu::AdapterPreference;

/// Particle smoke with interchangeable volumetric self-shadowing techniques, compared under one
/// channel budget.
#[derive(Parser)]
#[command(version, about, propagate_version = true)]
struct Cli {
    /// Which GPU adapter to use: auto (hardware first), cpu (lavapipe), or part of a name.
    #[arg(
        long,
        global = true,
        default_value = "auto",
        env = "SMOKESHADOW_ADAPTER"
    )]
    adapter: AdapterPreference,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render one frame of a scene to PNG (and optionally benchmark it).
    Render(commands::render::RenderArgs),
    /// Print the transmittance at a point (or along the light ray through it) for a technique
    /// and for the exact reference.
    Probe(commands::probe::ProbeArgs),
    /// Show the GPU adapters, the selected one's capabilities, and the techniques; or, given an
    /// OpenVDB file, its grids.
    Info(commands::info::InfoArgs),
    /// Compare two images: FLIP, RMSE, PSNR, SSIM, and the thesis' 4x-enhanced difference.
    Diff(commands::diff::DiffArgs),
    /// Open the interactive viewer: switch techniques and budgets live, compare them side by
    /// side, against their baselines and the exact reference.
    View(commands::view::ViewArgs),
    /// Sweep techniques x channel budgets x shadow resolutions: time, bytes and error as CSV,
    /// JSON, SVG charts and an HTML report (default: the thesis experiment).
    Sweep(commands::sweep::SweepArgs),
    /// Choose every technique's parameters by one procedure on training scenes (apart from the
    /// thesis and gallery scenes), check them on held-out scenes, and write a parameter file
    /// (`--params FILE`).
    Tune(commands::tune::TuneArgs),
    /// Check the committed 24-channel baselines against fresh renders, or bless new ones.
    Baseline(commands::baseline::BaselineArgs),
    /// The thesis' accuracy comparison for a scene: images, differences, metrics.csv and an
    /// HTML page.
    Compare(commands::compare::CompareArgs),
    /// Cost against particle count (default: plume_scaled at 2,500 to 1,000,000 particles):
    /// simulation, sort, every GPU pass, each technique's frame and bytes, as a table, CSV,
    /// JSON and log-log SVG charts.
    Bench(commands::bench::BenchArgs),
    /// Write a scene's particles (simulated, or read from its particle file) as PLY or CSV, at
    /// one time or as a numbered sequence of frames.
    Particles(commands::particles::ParticlesArgs),
}

fn main() -> ExitCode {
    // Printing into a closed pipe (`smokeshadow info | head -1`) ends the process quietly, as
    // for any Unix tool, instead of panicking on the failed write.
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    smokeshadow::gpu::quiet_device_select_layer();
    // wgpu-core warns, over several lines, that an adapter is not a fully compliant WebGPU
    // implementation (lavapipe on a CPU without F16C lacks SHADER_F16_IN_F32): nothing the tool
    // uses, so that module speaks only of errors unless RUST_LOG says otherwise.
    env_logger::Builder::from_env(
        env_logger::Env::default().default_filter_or("warn,wgpu_core::instance=error"),
    )
    .init();
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(err) => {
            use clap::error::ErrorKind;
            if matches!(
                err.kind(),
                ErrorKind::DisplayHelp
                    | ErrorKind::DisplayVersion
                    | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
            ) {
                let _ = err.print();
                return ExitCode::SUCCESS;
            }
            // One line: clap's first paragraph names the problem and the argument (a missing
            // argument's name is on the lines under "were not provided:").
            let text = err.render().to_string();
            let line: Vec<&str> = text
                .lines()
                .skip_while(|l| l.trim().is_empty())
                .take_while(|l| !l.trim().is_empty())
                .map(str::trim)
                .collect();
            match line.is_empty() {
                true => eprintln!("invalid arguments"),
                false => eprintln!("{}", line.join(" ")),
            }
            return ExitCode::from(2);
        }
    };
    let result = match &cli.command {
        Command::Render(args) => {
            commands::render::run(args, &cli.adapter).map(|()| ExitCode::SUCCESS)
        }
        Command::Probe(args) => {
            commands::probe::run(args, &cli.adapter).map(|()| ExitCode::SUCCESS)
        }
        Command::Info(args) => commands::info::run(args, &cli.adapter).map(|()| ExitCode::SUCCESS),
        Command::Diff(args) => commands::diff::run(args),
        Command::Baseline(args) => commands::baseline::run(args, &cli.adapter),
        Command::View(args) => commands::view::run(args, &cli.adapter).map(|()| ExitCode::SUCCESS),
        Command::Sweep(args) => {
            commands::sweep::run(args, &cli.adapter).map(|()| ExitCode::SUCCESS)
        }
        Command::Tune(args) => commands::tune::run(args, &cli.adapter).map(|()| ExitCode::SUCCESS),
        Command::Compare(args) => {
            commands::compare::run(args, &cli.adapter).map(|()| ExitCode::SUCCESS)
        }
        Command::Bench(args) => {
            commands::bench::run(args, &cli.adapter).map(|()| ExitCode::SUCCESS)
        }
        Command::Particles(args) => commands::particles::run(args).map(|()| ExitCode::SUCCESS),
    };
    match result {
        Ok(code) => code,
        Err(err) => {
            eprintln!("error: {}", format!("{err:#}").replace('\n', " "));
            // Like ImageMagick's `compare`: 1 means "ran, and found a difference over a
            // threshold" (diff, baseline --check); an error is 2.
            ExitCode::from(2)
        }
    }
}
