//! Display models: tiles, the unrolled canvas, and the mappings between canvas, tile, 3D point
//! and image pixel (DESIGN.md §3).
