//! The region of interest and the distance-guide image (DESIGN.md §4–5).

pub mod cone;
pub mod conic;
pub mod ellipse;
pub mod dgi;
pub mod gpu;
