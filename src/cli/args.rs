//! Parsers for the command line's comma-separated lists ("X,Y,Z", "W,H", "A,B").

use glam::{DVec2, DVec3};

use crate::gpu::{Backend, BackendChoice, GpuError};
use crate::messages::quote;
use crate::trace::camera::LookAt;

/// Why a command-line list did not parse.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ListParseError {
    #[error(
        "{}: expected {expected} comma-separated numbers ({form}), found {found}",
        quote(text)
    )]
    Count {
        text: String,
        expected: usize,
        found: usize,
        form: &'static str,
    },
    #[error("{}: item {index} ({}) is not a number", quote(text), quote(item))]
    NotANumber {
        text: String,
        index: usize,
        item: String,
    },
    #[error("{}: item {index} ({}) is not finite", quote(text), quote(item))]
    NonFinite {
        text: String,
        index: usize,
        item: String,
    },
    #[error(
        "{}: item {index} ({}) is not a whole number from 1 to {}",
        quote(text),
        quote(item),
        u32::MAX
    )]
    NotAPositiveInteger {
        text: String,
        index: usize,
        item: String,
    },
}

fn floats<const N: usize>(text: &str, form: &'static str) -> Result<[f64; N], ListParseError> {
    let items: Vec<&str> = text.split(',').map(str::trim).collect();
    if items.len() != N {
        return Err(ListParseError::Count {
            text: text.to_owned(),
            expected: N,
            found: items.len(),
            form,
        });
    }
    let mut out = [0.0; N];
    for (index, (slot, item)) in out.iter_mut().zip(&items).enumerate() {
        let v: f64 = item.parse().map_err(|_| ListParseError::NotANumber {
            text: text.to_owned(),
            index: index + 1,
            item: (*item).to_owned(),
        })?;
        if !v.is_finite() {
            return Err(ListParseError::NonFinite {
                text: text.to_owned(),
                index: index + 1,
                item: (*item).to_owned(),
            });
        }
        *slot = v;
    }
    Ok(out)
}

/// "X,Y,Z" → a finite vector.
pub fn parse_vec3(text: &str) -> Result<DVec3, ListParseError> {
    floats::<3>(text, "X,Y,Z").map(DVec3::from_array)
}

/// "A,B" → a finite pair.
pub fn parse_pair(text: &str) -> Result<DVec2, ListParseError> {
    floats::<2>(text, "A,B").map(DVec2::from_array)
}

/// `--backend`: where the stages run, the same flag in every command that renders.
#[derive(Clone, Copy, Debug, clap::Args)]
pub struct BackendArgs {
    #[arg(long, value_enum, default_value_t = BackendChoice::Auto)]
    pub backend: BackendChoice,
}

impl BackendArgs {
    /// The backend `--backend` names ([`Backend::select`]).
    pub fn select(&self) -> Result<Backend, GpuError> {
        Backend::select(self.backend)
    }

    /// The backend `--backend` names and a note on the choice ([`Backend::choose`]).
    pub fn choose(&self) -> Result<(Backend, Option<String>), GpuError> {
        Backend::choose(self.backend)
    }
}

/// `--look-from X,Y,Z --look-at X,Y,Z [--yfov DEG]`: a viewpoint instead of a scene camera,
/// the same flags in `render` and `view`.
#[derive(Clone, Copy, Debug, Default, clap::Args)]
pub struct LookArgs {
    /// Look from this point (X,Y,Z, metres, the scene's frame) instead of a scene camera;
    /// needs --look-at.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, requires = "look_at", conflicts_with = "camera", allow_hyphen_values = true)]
    pub look_from: Option<DVec3>,
    /// The point --look-from looks at (+Y up).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, requires = "look_from", allow_hyphen_values = true)]
    pub look_at: Option<DVec3>,
    /// Vertical field of view of --look-from, degrees (default 45).
    #[arg(long, value_name = "DEG", requires = "look_from")]
    pub yfov: Option<f32>,
}

impl LookArgs {
    /// The viewpoint the flags give (clap makes `--look-from` and `--look-at` go together).
    #[must_use]
    pub fn viewpoint(&self) -> Option<LookAt> {
        Some(LookAt {
            from: self.look_from?.as_vec3(),
            at: self.look_at?.as_vec3(),
            yfov_deg: self.yfov.unwrap_or(45.0),
        })
    }
}

/// `--size native` as parsed, before the display is known: [`resolve_size`] replaces it with the
/// canvas's own pixel size. No real size is 0×0 ([`parse_size`] refuses zeros).
pub const NATIVE_SIZE: [u32; 2] = [0, 0];

/// "W,H", or "native" ([`NATIVE_SIZE`]: the display canvas's own pixel size, resolved by
/// [`resolve_size`] once the command's display is open).
pub fn parse_size_or_native(text: &str) -> Result<[u32; 2], ListParseError> {
    if text.trim().eq_ignore_ascii_case("native") {
        return Ok(NATIVE_SIZE);
    }
    parse_size(text)
}

/// `size`, with `--size native` replaced by the pixel size of `display`'s canvas (the size at
/// which `--tiles` cuts every tile at its own resolution, DESIGN.md §3).
pub fn resolve_size(size: [u32; 2], display: &str) -> anyhow::Result<[u32; 2]> {
    if size != NATIVE_SIZE {
        return Ok(size);
    }
    let (model, _) = crate::display::DisplayModel::open(display).map_err(|e| {
        anyhow::anyhow!("--size native is the canvas size of --display {display}: {e}")
    })?;
    Ok(crate::output::tiles::canvas_pixel_size(&model))
}

/// "W,H" → two whole numbers ≥ 1.
pub fn parse_size(text: &str) -> Result<[u32; 2], ListParseError> {
    let items: Vec<&str> = text.split(',').map(str::trim).collect();
    if items.len() != 2 {
        return Err(ListParseError::Count {
            text: text.to_owned(),
            expected: 2,
            found: items.len(),
            form: "W,H",
        });
    }
    let mut out = [0u32; 2];
    for (index, (slot, item)) in out.iter_mut().zip(&items).enumerate() {
        *slot = item.parse::<u32>().ok().filter(|&v| v > 0).ok_or_else(|| {
            ListParseError::NotAPositiveInteger {
                text: text.to_owned(),
                index: index + 1,
                item: (*item).to_owned(),
            }
        })?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vec3_accepts_negatives_spaces_and_exponents() {
        assert_eq!(
            parse_vec3("-1, 2.5 ,3e-1").unwrap(),
            DVec3::new(-1.0, 2.5, 0.3)
        );
    }

    #[test]
    fn vec3_rejects_wrong_count_naming_what_was_found() {
        let e = parse_vec3("1,2").unwrap_err();
        assert_eq!(
            e,
            ListParseError::Count {
                text: "1,2".into(),
                expected: 3,
                found: 2,
                form: "X,Y,Z"
            }
        );
        assert!(e.to_string().contains("X,Y,Z"), "{e}");
        assert!(matches!(
            parse_vec3("1,2,3,4"),
            Err(ListParseError::Count { found: 4, .. })
        ));
    }

    #[test]
    fn vec3_names_the_bad_item() {
        let e = parse_vec3("1,x,3").unwrap_err();
        assert!(
            matches!(e, ListParseError::NotANumber { index: 2, .. }),
            "{e:?}"
        );
        assert!(matches!(
            parse_vec3("1,,3"),
            Err(ListParseError::NotANumber { index: 2, .. })
        ));
        assert!(matches!(
            parse_vec3("nan,0,0"),
            Err(ListParseError::NonFinite { index: 1, .. })
        ));
        assert!(matches!(
            parse_vec3("0,0,inf"),
            Err(ListParseError::NonFinite { index: 3, .. })
        ));
    }

    #[test]
    fn size_needs_two_positive_integers() {
        assert_eq!(parse_size("3840,2160").unwrap(), [3840, 2160]);
        assert!(matches!(
            parse_size("0,2160"),
            Err(ListParseError::NotAPositiveInteger { index: 1, .. })
        ));
        assert!(matches!(
            parse_size("3840,-1"),
            Err(ListParseError::NotAPositiveInteger { index: 2, .. })
        ));
        assert!(matches!(
            parse_size("3840.5,2160"),
            Err(ListParseError::NotAPositiveInteger { .. })
        ));
        assert!(matches!(
            parse_size("3840"),
            Err(ListParseError::Count { found: 1, .. })
        ));
    }

    #[test]
    fn pair_parses_and_names_the_bad_item() {
        assert_eq!(parse_pair("1,-2").unwrap(), DVec2::new(1.0, -2.0));
        assert!(matches!(
            parse_pair("1,x"),
            Err(ListParseError::NotANumber { index: 2, .. })
        ));
        assert!(matches!(
            parse_pair("1,inf"),
            Err(ListParseError::NonFinite { index: 2, .. })
        ));
        assert!(matches!(
            parse_pair("1"),
            Err(ListParseError::Count { found: 1, .. })
        ));
    }

    /// The reports' metric names are the command line's.
    #[test]
    fn metric_names_are_the_flags_values() {
        use crate::roi::dgi::Metric;
        use clap::ValueEnum;
        for m in Metric::value_variants() {
            assert_eq!(m.to_possible_value().unwrap().get_name(), m.name());
        }
    }
}
