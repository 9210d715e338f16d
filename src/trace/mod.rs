//! Path tracing (DESIGN.md §7): the BVH, the WGSL integrator and its CPU twin.

pub mod accum;

pub use accum::{Accumulation, luminance};
