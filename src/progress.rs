//! Progress on a terminal for long work: one bar style for every command (the sweep's cells,
//! the simulation's steps), drawn on stderr only when stderr is a terminal, so that test output
//! and CI logs stay clean.

use std::io::IsTerminal;

use smokeshadow_core::scene::Scene;
use smokeshadow_core::sim::{Particle, Simulation};

/// A simulation with at least this many particle-steps (particles x fixed steps) gets a bar:
/// a step costs ~0.1 µs per particle on one core, so this is ~0.4 s of single-threaded work
/// (the thesis' 2,500 particles over 480 steps stay silent).
pub const LONG_SIMULATION_PARTICLE_STEPS: u64 = 4_000_000;

/// A bar of `len` `unit`s (with elapsed time, ETA and a message), or `None` when stderr is not
/// a terminal.
pub fn bar(len: u64, unit: &str) -> Option<indicatif::ProgressBar> {
    if !std::io::stderr().is_terminal() {
        return None;
    }
    let bar = indicatif::ProgressBar::new(len);
    bar.set_style(
        indicatif::ProgressStyle::with_template(&format!(
            "{{spinner}} [{{elapsed_precise}}] {{bar:30}} {{pos}}/{{len}} {unit}, ETA {{eta}} {{msg}}"
        ))
        .expect("a valid progress template")
        .progress_chars("=> "),
    );
    Some(bar)
}

/// [`crate::sim::simulate`] of `scene`, with a bar of its steps on a terminal when the run is
/// long ([`LONG_SIMULATION_PARTICLE_STEPS`]). The particles are the same either way.
pub fn simulate(scene: &Scene) -> Vec<Particle> {
    let mut sim = Simulation::new(scene);
    let steps = smokeshadow_core::sim::step_index(scene.sim.step_s, scene.sim.duration_s);
    let work = steps.saturating_mul(scene.particle_count());
    let shown = if work >= LONG_SIMULATION_PARTICLE_STEPS {
        bar(steps, "steps")
    } else {
        None
    };
    match &shown {
        Some(bar) => {
            bar.set_message(format!("simulating {} particles", scene.particle_count()));
            sim.advance_to_reporting(scene.sim.duration_s, &mut |done, _| bar.set_position(done));
            bar.finish_and_clear();
        }
        None => sim.advance_to(scene.sim.duration_s),
    }
    sim.particles()
}

/// A count of finished items: a [`bar`] with an ETA on a terminal, a plain `[i/n] line` per item
/// on stderr otherwise (CI logs).
pub struct Progress {
    bar: Option<indicatif::ProgressBar>,
    total: usize,
    done: usize,
}

impl Progress {
    /// Progress over `total` items, counted in `unit` ("cells").
    pub fn new(total: usize, unit: &str) -> Self {
        Self {
            bar: bar(total as u64, unit),
            total,
            done: 0,
        }
    }

    /// Names the item now in progress (shown beside the bar).
    pub fn start(&self, what: &str) {
        if let Some(bar) = &self.bar {
            bar.set_message(what.to_owned());
        }
    }

    /// Counts one item as finished and prints its line above the bar.
    pub fn finish(&mut self, line: String) {
        self.done += 1;
        match &self.bar {
            Some(bar) => {
                bar.println(line);
                bar.inc(1);
            }
            None => eprintln!("[{}/{}] {line}", self.done, self.total),
        }
    }

    /// Runs `f` with the bar hidden (for work that draws its own bar, such as [`simulate`]).
    pub fn suspend<T>(&self, f: impl FnOnce() -> T) -> T {
        match &self.bar {
            Some(bar) => bar.suspend(f),
            None => f(),
        }
    }

    /// Clears the bar.
    pub fn end(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}
