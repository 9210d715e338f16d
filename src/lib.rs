//! raygun — guided high-quality rendering.
//!
//! The pipeline of `docs/DESIGN.md` §1, one module per stage:
//!
//! ```text
//! tracking ──► interaction ──► display ──► roi (DGI) ──► schedule ──► trace ──► filter ──► output
//! ```
//!
//! Every stage that runs on the GPU has a kernel in `shaders/<stage>/` and a CPU twin in
//! `src/<stage>/` computing the same function; the twin is the test oracle and the fallback
//! backend when no GPU adapter exists.
//!
//! The display, ROI and DGI stages on the CPU twin, for a ray gun held 1 m in front of the
//! HORNET wall's centre:
//!
//! ```
//! use glam::DVec3;
//! use raygun::display::DisplayModel;
//! use raygun::roi::cone::Cone;
//! use raygun::roi::dgi::{DgiParams, Falloff, Guide, Metric, Roi, Surface, compute_cpu, roi_radius_m};
//!
//! let model = DisplayModel::load(concat!(env!("CARGO_MANIFEST_DIR"), "/display-models/hornet.json"))?;
//! let hit = model.intersect(DVec3::new(0.0, 0.0, 1.0), DVec3::NEG_Z).expect("the centre is on the wall");
//! assert_eq!(hit.tile_id, "c3r2");
//!
//! let roi = Roi::Cone(Cone::from_pose(DVec3::new(0.0, 0.0, 1.0), DVec3::NEG_Z, DVec3::Y, 30.0, 30.0)?);
//! let surface = Surface::from_model(&model);
//! let length_px = Falloff::default().length_px(roi_radius_m(&surface, &roi), model.pitch_m());
//! let guide = Guide::new(&surface, &roi, Metric::Exact)?;
//! let params = DgiParams { width: 64, height: 36, falloff_px: Some(length_px) };
//! let dgi = compute_cpu(&surface, &guide, &params);
//! assert_eq!(dgi[18 * 64 + 32], 0.0); // the centre pixel is inside the ROI
//! assert_eq!(dgi[0], 1.0); // the top-left corner is beyond the falloff
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

// `!(x > 0.0)` is how this crate rejects NaN together with the out-of-range values; clippy's
// suggested `partial_cmp` form would hide that intent.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod bench;
pub mod cli;
pub mod cluster;
pub mod display;
pub mod filter;
pub mod frame;
pub mod gpu;
pub mod input;
pub mod interaction;
pub mod memory;
pub mod messages;
pub mod output;
pub mod random;
pub mod roi;
pub mod scene;
pub mod schedule;
pub mod session;
pub mod trace;
pub mod tracking;
pub mod viewer;
