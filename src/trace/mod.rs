//! Path tracing (DESIGN.md §7): the BVH, the WGSL integrator and its CPU twin.

pub mod accum;
pub mod bvh;
pub mod camera;
pub mod features;
pub mod gpu;
pub mod lanes;
pub mod pack;
pub mod path;
pub mod reuse;
pub mod shading;
pub mod wall;

pub use accum::{Accumulation, luminance};
