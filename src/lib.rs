//! smokeshadow: particle smoke with interchangeable volumetric self-shadowing techniques, all
//! measured under the same channel budget (Giuliatti 2013, *Rendering Techniques for Cloud
//! Volume Densities with Shadows*). See ARCHITECTURE.md for the data flow and the file map.

pub mod baseline;
pub mod bench;
pub mod commands;
pub mod compare;
pub mod diff;
pub mod frame;
pub mod gpu;
pub mod medium;
pub mod motion;
pub mod output;
pub mod particles;
pub mod progress;
pub mod render;
pub mod report;
pub mod scene;
pub mod shaders;
pub mod shadow;
pub mod sim;
pub mod sweep;
pub mod tune;
pub mod viewer;
