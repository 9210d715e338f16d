//! The display walls and the DGI over them: the display-model files, their geometry, the
//! closest-point solver's hard cases, and the DGI's properties and block pruning.

mod dgi_blocks;
mod dgi_properties;
mod display_geometry;
mod display_models;
mod ellipse_hard_cases;

// The helpers of tests/support/ that the files above use, each compiled once here.
#[path = "../support/walls.rs"]
mod walls;
