//! The display walls and the DGI over them: the display-model files, their geometry, the
//! closest-point solver's hard cases, the DGI's properties and block pruning, and
//! the output maps of the screens.

mod dgi_blocks;
mod dgi_properties;
mod display_geometry;
mod display_models;
mod ellipse_hard_cases;
mod outputs_cli;

// The helpers of tests/support/ that the files above use, each compiled once here.
#[path = "../support/cli.rs"]
mod support;
#[path = "../support/walls.rs"]
mod walls;
