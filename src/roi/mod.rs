//! The region of interest and the distance-guide image (DESIGN.md §4–5).

pub mod ellipse;
