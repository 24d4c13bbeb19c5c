//! The media smoke is made of. Today the particles (`crate::sim`, `crate::particles`); next,
//! density volumes (issue 26): grids of extinction that the eye ray-marches and every technique
//! builds its shadow from in light space, as the 2022 dissertation (`../shared/seeds/000_...txt`)
//! and the 2018 cloud thesis (`004_...txt`) shadow their clouds. Not to be confused with the
//! `volume` technique (`crate::shadow::volume`), a light-space extinction volume built from
//! either medium.
//!
//! - [`analytic`]: homogeneous spheres and boxes with closed-form transmittance, the volumes'
//!   exact test cases.
//! - [`grid`]: a dense density grid in the world and its converged f64 march, the CPU mirror
//!   of the volumes' reference.
//! - [`gpu_grid`]: the grid on the GPU and its fixed-step transmittance march at world points
//!   (`shaders/medium/`), held to `grid` at the same steps.
//!
//! - [`vdb`]: the OpenVDB reader (float grids, safe on any input), for simulated smoke from
//!   Houdini, Blender or EmberGen (`smokeshadow info FILE.vdb`).
//! - [`cloud_noise`] and [`cloud`]: the procedural cloud's tileable Perlin–Worley and Worley
//!   noise (the slides' and the 2018 thesis' model), on the CPU and generated on the GPU.
//!
//! - [`eye`]: the eye's front-to-back ray march (`shaders/medium/eye_march.wgsl`) and a probe
//!   of it at rays, with the light's transmittance by secondary ray marching.
//!
//! - [`scene`]: the scene's `[volume]` made into a grid (a file, the cloud, a shape), and a bare
//!   `.vdb` as a scene.
//! - [`frame`]: the volume in the frame (group 0's voxels, the frame uniforms' `grid`), loaded
//!   once per source; [`eye_pass`]: the eye's march in the frame and its composite. The
//!   techniques' shared light-space build from it is `shaders/shadow/volume_splat.wgsl`.

pub mod analytic;
pub mod cloud;
pub mod cloud_noise;
pub mod eye;
pub mod eye_pass;
pub mod frame;
pub mod gpu_grid;
pub mod grid;
pub mod scene;
pub mod vdb;
