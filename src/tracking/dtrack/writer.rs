//! The inverse of the `6df2` parser, for the synthesiser (`interaction::synth`) and tests.

use super::*;

/// Formats one FlyStick as a `6df2` line body (used by the synthetic session generator and
/// tests; the inverse of the parser up to printing precision).
#[must_use]
pub fn format_flystick_block(
    id: u32,
    pose_mm: Option<(DVec3, DMat3)>,
    button_count: u32,
    buttons: u32,
    axes: &[f64],
) -> String {
    use std::fmt::Write;
    let mut s = String::with_capacity(200);
    let quality = if pose_mm.is_some() { 1.0 } else { -1.0 };
    let _ = write!(s, "[{id} {quality:.3} {button_count} {}]", axes.len());
    match pose_mm {
        Some((p, r)) => {
            let _ = write!(s, "[{:.3} {:.3} {:.3}][", p.x, p.y, p.z);
            for (i, v) in r.to_cols_array().iter().enumerate() {
                let sep = if i == 0 { "" } else { " " };
                let _ = write!(s, "{sep}{v:.6}");
            }
            s.push(']');
        }
        None => {
            s.push_str("[0.000 0.000 0.000][0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000]");
        }
    }
    let _ = write!(s, "[{buttons}");
    for a in axes {
        let _ = write!(s, " {a:.6}");
    }
    s.push(']');
    s
}
