//! raygun — guided high-quality rendering.
//!
//! The pipeline of `DESIGN.md` §1, one module per stage:
//!
//! ```text
//! tracking ──► interaction ──► display ──► roi (DGI) ──► schedule ──► trace ──► filter ──► output
//! ```
//!
//! Every stage that runs on the GPU has a kernel in `shaders/<stage>/` and a CPU twin in
//! `src/<stage>/` computing the same function; the twin is the test oracle and the fallback
//! backend when no GPU adapter exists.

// `!(x > 0.0)` is how this crate rejects NaN together with the out-of-range values; clippy's
// suggested `partial_cmp` form would hide that intent.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod bench;
pub mod cli;
pub mod display;
pub mod gpu;
pub mod interaction;
pub mod output;
pub mod roi;
pub mod tracking;
