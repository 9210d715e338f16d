//! The region of interest and the distance-guide image (DESIGN.md §4–5).
//!
//! `cone` is the ray gun's frozen cone; `conic` its exact projection on each planar tile and the
//! distance to it; `ellipse` the robust closest-point solver; `dgi` the image (CPU twin) and
//! `gpu` its kernel's dispatch (`shaders/roi/`).

pub mod cone;
pub mod conic;
pub mod dgi;
pub mod ellipse;
pub mod gpu;
