//! smokeshadow: particle smoke with interchangeable volumetric self-shadowing techniques, all
//! measured under the same channel budget (Giuliatti 2013, *Rendering Techniques for Cloud
//! Volume Densities with Shadows*). See ARCHITECTURE.md for the data flow and the file map.
//!
//! This package is the apps (the CLI, the viewer, the sweep, the baselines); the renderer and
//! everything it draws is the core, `smokeshadow-core` (`core/`), whose rooms are re-exported
//! here under their own names.

pub mod baseline;
pub mod bench;
pub mod commands;
pub mod compare;
pub mod diff;
pub mod output;
pub mod particles;
pub mod progress;
pub mod report;
pub mod sweep;
pub mod tune;
pub mod viewer;

pub use smokeshadow_core::{
    files, frame, gpu, medium, motion, render, scene, shaders, shadow, sim,
};

/// The native apps' edge: the core awaits every read-back from the GPU (on the web the browser
/// answers between tasks); a native app blocks on the core's futures here, `.wait()`, and
/// nowhere else.
pub trait Wait: std::future::Future + Sized {
    /// Runs the future to completion on this thread.
    fn wait(self) -> Self::Output {
        pollster::block_on(self)
    }
}

impl<F: std::future::Future> Wait for F {}
