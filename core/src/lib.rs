//! smokeshadow's core: the scene, the particle simulation, the media, the shadow techniques, the
//! frame that draws them and the image metrics that compare them (Giuliatti 2013, *Rendering
//! Techniques for Cloud Volume Densities with Shadows*).
//!
//! No command line, no window, no progress bar: bytes in, images and numbers out. It builds for
//! the host and for `wasm32-unknown-unknown`; the files a scene names are read through its
//! [`files::Files`], never opened behind the caller's back. The apps (the CLI and the viewer in
//! the workspace's root package, the web app) stand on it. See ARCHITECTURE.md.

pub mod diff;
pub mod files;
pub mod frame;
pub mod gpu;
pub mod medium;
pub mod motion;
pub mod particles;
pub mod render;
pub mod scene;
pub mod shaders;
pub mod shadow;
pub mod sim;
pub mod sweep;
