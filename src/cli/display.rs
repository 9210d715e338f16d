//! `raygun pick`, `raygun display expand` and `raygun display outputs`: arguments and command
//! logic.

use glam::{DVec2, DVec3};
use serde_json::{Value, json};

use crate::cli::args::{parse_size, parse_vec3};
use crate::display::DisplayModel;
use crate::display::outputs::OutputMap;

/// `raygun pick`: where does a ray meet the display?
#[derive(Clone, Debug, clap::Args)]
pub struct PickArgs {
    /// Display model: a file, or a built-in model (hornet, desktop-27in-4k, projection-4m-4k).
    #[arg(long, value_name = "MODEL", default_value = crate::display::DEFAULT_MODEL)]
    pub display: String,
    /// Ray origin in the room frame, metres.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub origin: DVec3,
    /// Ray direction in the room frame (any length but zero).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub dir: DVec3,
    /// Image size in pixels, W,H. `image_px` is a pixel of this image.
    #[arg(allow_hyphen_values = true, long, value_name = "W,H", value_parser = parse_size, default_value = "3840,2160")]
    pub size: [u32; 2],
}

/// `raygun display expand`: print a model's explicit form.
#[derive(Clone, Debug, clap::Args)]
pub struct ExpandArgs {
    /// Display model: a file (explicit or generator form), or a built-in model (hornet,
    /// desktop-27in-4k, projection-4m-4k).
    #[arg(value_name = "MODEL")]
    pub model: String,
}

/// `raygun pick`: loads the model and reports the first hit as one JSON object (see
/// [`pick_on`]).
pub fn pick(args: &PickArgs) -> anyhow::Result<Value> {
    let model = DisplayModel::open(&args.display)?.0;
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
    Ok(DisplayModel::open(&args.model)?.0.to_json_pretty())
}

/// `raygun display outputs`: write the output map of a regular grid of screens.
#[derive(Clone, Debug, clap::Args)]
pub struct OutputsArgs {
    /// Display model: a file, or a built-in model (hornet, desktop-27in-4k, projection-4m-4k).
    #[arg(value_name = "MODEL")]
    pub model: String,
    /// The model's tiles as a grid of COLSxROWS (by their column and row). Without it: one
    /// desktop spanning the whole canvas, each tile at its canvas position, bezels as gaps.
    #[arg(long, value_name = "COLSxROWS", value_parser = parse_grid)]
    pub grid: Option<[u32; 2]>,
    /// Tiles per desktop, COLSxROWS, side by side without gaps; blocks at the right and bottom
    /// edges hold the tiles that remain. Default: the whole grid on one desktop.
    #[arg(long, value_name = "COLSxROWS", value_parser = parse_grid, requires = "grid")]
    pub per_desktop: Option<[u32; 2]>,
    /// The map file to write (replaced atomically).
    #[arg(long, value_name = "FILE")]
    pub out: std::path::PathBuf,
}

/// A `COLSxROWS` value that is not one.
#[derive(Debug, PartialEq, thiserror::Error)]
pub enum GridParseError {
    #[error("expected COLSxROWS, two whole numbers from 1 (e.g. 7x5), got {0:?}")]
    Numbers(String),
    #[error("expected COLSxROWS (e.g. 7x5), got {0:?}")]
    Form(String),
}

/// `COLSxROWS`, each at least 1 (`7x5`).
pub fn parse_grid(s: &str) -> Result<[u32; 2], GridParseError> {
    let parse = |v: &str| v.trim().parse::<u32>().ok().filter(|&n| n >= 1);
    match s.split_once(['x', 'X']) {
        Some((c, r)) => match (parse(c), parse(r)) {
            (Some(c), Some(r)) => Ok([c, r]),
            _ => Err(GridParseError::Numbers(s.to_owned())),
        },
        None => Err(GridParseError::Form(s.to_owned())),
    }
}

/// `raygun display outputs`: builds the map (the grid's, or the model's default), writes it to
/// `--out` through a temporary name, and returns what it wrote, a line per desktop.
pub fn outputs(args: &OutputsArgs) -> anyhow::Result<String> {
    let (model, _) = DisplayModel::open(&args.model)?;
    let map = match args.grid {
        Some(grid) => OutputMap::grid(&model, grid, args.per_desktop.unwrap_or(grid))?,
        None => OutputMap::default_for(&model)?,
    };
    crate::output::file::write_bytes(&args.out, map.to_json_pretty().as_bytes())?;
    let mut lines = vec![format!(
        "{}: {} desktop(s) showing {} of the {} tiles of {}",
        args.out.display(),
        map.desktops().len(),
        map.desktops().iter().map(|d| d.tiles.len()).sum::<usize>(),
        model.tiles().len(),
        model.name()
    )];
    for d in map.desktops() {
        let ids: Vec<&str> = d.tiles.iter().map(|t| t.id.as_str()).collect();
        lines.push(format!(
            "  {}: {}×{}: {}",
            d.name,
            d.size[0],
            d.size[1],
            ids.join(" ")
        ));
    }
    Ok(lines.join("\n"))
}

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn grids_parse_and_bad_ones_are_named() {
        assert_eq!(parse_grid("7x5"), Ok([7, 5]));
        assert_eq!(parse_grid("1X5"), Ok([1, 5]));
        for bad in ["7", "0x5", "7x", "-1x5", "7x5x1", "axb"] {
            let e = parse_grid(bad).unwrap_err().to_string();
            assert!(e.contains("COLSxROWS") && e.contains(bad), "{e}");
        }
    }
}
