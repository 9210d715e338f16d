//! `raygun pick` and `raygun display expand`: arguments and command logic.

use std::path::PathBuf;

use glam::{DVec2, DVec3};
use serde_json::{Value, json};

use crate::display::DisplayModel;

/// `raygun pick`: where does a ray meet the display?
#[derive(Clone, Debug, clap::Args)]
pub struct PickArgs {
    /// Display model file (e.g. display-models/hornet.json).
    #[arg(long, value_name = "FILE")]
    pub display: PathBuf,
    /// Ray origin in the room frame, metres.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub origin: DVec3,
    /// Ray direction in the room frame (any length but zero).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub dir: DVec3,
    /// Rendered image size, for `image_px`.
    #[arg(long, value_name = "W,H", value_parser = parse_size, default_value = "3840,2160")]
    pub size: [u32; 2],
}

/// `raygun display expand`: print a model's explicit form.
#[derive(Clone, Debug, clap::Args)]
pub struct ExpandArgs {
    /// Display model file (explicit or generator form).
    #[arg(value_name = "FILE")]
    pub file: PathBuf,
}

/// Why a command-line list did not parse.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ListParseError {
    #[error("{text:?}: expected {expected} comma-separated numbers ({form}), found {found}")]
    Count {
        text: String,
        expected: usize,
        found: usize,
        form: &'static str,
    },
    #[error("{text:?}: item {index} ({item:?}) is not a number")]
    NotANumber {
        text: String,
        index: usize,
        item: String,
    },
    #[error("{text:?}: item {index} ({item:?}) is not finite")]
    NonFinite {
        text: String,
        index: usize,
        item: String,
    },
    #[error(
        "{text:?}: item {index} ({item:?}) is not a whole number from 1 to {}",
        u32::MAX
    )]
    NotAPositiveInteger {
        text: String,
        index: usize,
        item: String,
    },
}

/// Splits `text` at commas into exactly `N` trimmed items (item numbers are 1-based in errors).
fn split_n<'a, const N: usize>(
    text: &'a str,
    form: &'static str,
) -> Result<[&'a str; N], ListParseError> {
    let items: Vec<&str> = text.split(',').map(str::trim).collect();
    items
        .try_into()
        .map_err(|items: Vec<&str>| ListParseError::Count {
            text: text.to_owned(),
            expected: N,
            found: items.len(),
            form,
        })
}

/// Parses "X,Y,Z" (spaces around the numbers allowed) into finite f64s.
pub fn parse_vec3(text: &str) -> Result<DVec3, ListParseError> {
    let items = split_n::<3>(text, "X,Y,Z")?;
    let mut v = [0.0; 3];
    for (i, item) in items.iter().enumerate() {
        let x: f64 = item.parse().map_err(|_| ListParseError::NotANumber {
            text: text.to_owned(),
            index: i + 1,
            item: (*item).to_owned(),
        })?;
        if !x.is_finite() {
            return Err(ListParseError::NonFinite {
                text: text.to_owned(),
                index: i + 1,
                item: (*item).to_owned(),
            });
        }
        v[i] = x;
    }
    Ok(DVec3::from_array(v))
}

/// Parses "W,H" into two positive pixel counts.
pub fn parse_size(text: &str) -> Result<[u32; 2], ListParseError> {
    let items = split_n::<2>(text, "W,H")?;
    let mut v = [0; 2];
    for (i, item) in items.iter().enumerate() {
        v[i] = item.parse::<u32>().ok().filter(|&n| n > 0).ok_or_else(|| {
            ListParseError::NotAPositiveInteger {
                text: text.to_owned(),
                index: i + 1,
                item: (*item).to_owned(),
            }
        })?;
    }
    Ok(v)
}

/// `raygun pick`: loads the model and reports the first hit as one JSON object (see
/// [`pick_on`]).
pub fn pick(args: &PickArgs) -> anyhow::Result<Value> {
    let model = DisplayModel::load(&args.display)?;
    pick_on(&model, args.origin, args.dir, args.size)
}

/// The hit of the ray `origin + t·dir` on `model` as
/// `{"hit":true,"tile":ID,"tile_index":I,"tile_px":[x,y],"canvas_px":[x,y],"image_px":[x,y],
/// "point":[x,y,z],"t":T,"on_bezel":B}` (`t` in metres, pixel centres at `i + 0.5`), or
/// `{"hit":false}`. Rejects non-finite input, a zero direction and an empty image size.
pub fn pick_on(
    model: &DisplayModel,
    origin: DVec3,
    dir: DVec3,
    size: [u32; 2],
) -> anyhow::Result<Value> {
    anyhow::ensure!(origin.is_finite(), "--origin must be finite, got {origin}");
    anyhow::ensure!(
        dir.is_finite() && dir.length_squared() > 0.0,
        "--dir must be a finite, non-zero direction, got {dir}"
    );
    anyhow::ensure!(size[0] > 0 && size[1] > 0, "--size must be positive");
    let Some(hit) = model.intersect(origin, dir) else {
        return Ok(json!({ "hit": false }));
    };
    let image_px: DVec2 = model.canvas_to_image(hit.canvas_px, size);
    Ok(json!({
        "hit": true,
        "tile": hit.tile_id,
        "tile_index": hit.tile,
        "tile_px": hit.tile_px.to_array(),
        "canvas_px": hit.canvas_px.to_array(),
        "image_px": image_px.to_array(),
        "point": hit.point.to_array(),
        "t": hit.t,
        "on_bezel": hit.on_bezel,
    }))
}

/// `raygun display expand`: the model's explicit form as pretty JSON (no trailing newline). It
/// loads back into the same model.
pub fn expand(args: &ExpandArgs) -> anyhow::Result<String> {
    // The loader's errors already name the file, tile and field.
    Ok(DisplayModel::load(&args.file)?.to_json_pretty())
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

    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        pick: PickArgs,
    }

    #[test]
    fn clap_takes_negative_triples_and_defaults_the_size() {
        use clap::Parser;
        let cli = Cli::try_parse_from([
            "pick",
            "--display",
            "m.json",
            "--origin",
            "-1,0,1",
            "--dir",
            "0,-0.5,-1",
        ])
        .unwrap();
        assert_eq!(cli.pick.origin, DVec3::new(-1.0, 0.0, 1.0));
        assert_eq!(cli.pick.dir, DVec3::new(0.0, -0.5, -1.0));
        assert_eq!(cli.pick.size, [3840, 2160]);
        let err = Cli::try_parse_from([
            "pick",
            "--display",
            "m.json",
            "--origin",
            "1,0",
            "--dir",
            "0,0,-1",
        ])
        .err()
        .unwrap()
        .to_string();
        assert!(err.contains("expected 3 comma-separated numbers"), "{err}");
    }
}
