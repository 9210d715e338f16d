//! `--camera wall --eye X,Y,Z [--world-from-room auto|identity|X,Y,Z,YAW_DEG[,SCALE]]`: the
//! wall camera's flags (DESIGN.md §11), shared by `render` and the benchmarks.

use anyhow::{Context, bail};
use glam::DVec3;

use crate::display::DisplayModel;
use crate::messages::quote;
use crate::trace::wall::{WallSpec, WorldFromRoom};

/// The `--camera` value that selects the wall camera (any other value names a scene camera).
pub const WALL_CAMERA: &str = "wall";

/// The wall camera's own flags.
#[derive(Clone, Debug, Default, clap::Args)]
pub struct WallArgs {
    /// The eye of `--camera wall`: X,Y,Z in the room frame (metres, +Z from the wall towards
    /// the viewer), in front of every tile of --display.
    #[arg(long, value_name = "X,Y,Z", value_parser = crate::cli::args::parse_vec3, allow_hyphen_values = true)]
    pub eye: Option<DVec3>,
    /// Where `--camera wall`'s room sits in the scene: auto (the scene's camera at the eye,
    /// looking at the wall's centre), identity (the room frame is the scene's), or
    /// X,Y,Z,YAW_DEG or X,Y,Z,YAW_DEG,SCALE (scene = X,Y,Z + yaw about +Y · SCALE · room; SCALE default 1).
    #[arg(long, value_name = "auto|identity|X,Y,Z,YAW_DEG[,SCALE]", value_parser = parse_world_from_room, allow_hyphen_values = true)]
    pub world_from_room: Option<WorldFromRoom>,
}

/// Why a `--world-from-room` value did not parse.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum WorldFromRoomError {
    #[error(
        "{}: expected auto, identity or X,Y,Z,YAW_DEG[,SCALE] (4 or 5 numbers), found {found} items",
        quote(text)
    )]
    Count { text: String, found: usize },
    #[error(
        "{}: item {index} ({}) is not a finite number",
        quote(text),
        quote(item)
    )]
    NotFinite {
        text: String,
        index: usize,
        item: String,
    },
    #[error("{}: SCALE must be above 0 (scene units per metre)", quote(text))]
    Scale { text: String },
}

/// Parses `--world-from-room`.
pub fn parse_world_from_room(text: &str) -> Result<WorldFromRoom, WorldFromRoomError> {
    match text.trim() {
        "auto" => return Ok(WorldFromRoom::Auto),
        "identity" => return Ok(WorldFromRoom::Identity),
        _ => {}
    }
    let items: Vec<&str> = text.split(',').map(str::trim).collect();
    if !(4..=5).contains(&items.len()) {
        return Err(WorldFromRoomError::Count {
            text: text.to_owned(),
            found: items.len(),
        });
    }
    let mut v = [0.0f64, 0.0, 0.0, 0.0, 1.0];
    for (i, item) in items.iter().enumerate() {
        v[i] = item
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| WorldFromRoomError::NotFinite {
                text: text.to_owned(),
                index: i + 1,
                item: (*item).to_owned(),
            })?;
    }
    if v[4] <= 0.0 {
        return Err(WorldFromRoomError::Scale {
            text: text.to_owned(),
        });
    }
    Ok(WorldFromRoom::Explicit {
        translation: DVec3::new(v[0], v[1], v[2]),
        yaw_deg: v[3],
        scale: v[4],
    })
}

/// The wall camera the flags ask for, checked against the display (`None`: another camera).
/// `camera` is `--camera`, `display` the model `--display` names (already opened; `None`
/// when the flag is missing).
pub fn wall_spec(
    camera: Option<&str>,
    wall: &WallArgs,
    display: Option<&DisplayModel>,
) -> anyhow::Result<Option<WallSpec>> {
    wall_spec_or_eye(camera, wall, display, None)
}

/// [`wall_spec`] with `head_eye` (a tracked head's first eye) standing in for a missing
/// `--eye`.
pub fn wall_spec_or_eye(
    camera: Option<&str>,
    wall: &WallArgs,
    display: Option<&DisplayModel>,
    head_eye: Option<DVec3>,
) -> anyhow::Result<Option<WallSpec>> {
    if camera != Some(WALL_CAMERA) {
        if wall.eye.is_some() {
            bail!("--eye is the eye of the wall camera: it needs --camera wall");
        }
        if wall.world_from_room.is_some() {
            bail!("--world-from-room places the wall camera's room: it needs --camera wall");
        }
        return Ok(None);
    }
    let Some(model) = display else {
        bail!(
            "--camera wall needs --display MODEL: the display whose pixels the primary rays pass through"
        );
    };
    let Some(eye) = wall.eye.or(head_eye) else {
        bail!("--camera wall needs --eye X,Y,Z (the eye in the room frame, metres)");
    };
    let spec = WallSpec {
        model: model.clone(),
        eye,
        placement: wall.world_from_room.unwrap_or(WorldFromRoom::Auto),
    };
    spec.check().context("--camera wall")?;
    Ok(Some(spec))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn world_from_room_forms() {
        assert_eq!(parse_world_from_room("auto"), Ok(WorldFromRoom::Auto));
        assert_eq!(
            parse_world_from_room("identity"),
            Ok(WorldFromRoom::Identity)
        );
        assert_eq!(
            parse_world_from_room("1,2,3,90"),
            Ok(WorldFromRoom::Explicit {
                translation: DVec3::new(1.0, 2.0, 3.0),
                yaw_deg: 90.0,
                scale: 1.0
            })
        );
        assert!(parse_world_from_room("1,2,3").is_err());
        assert!(parse_world_from_room("1,2,3,x").is_err());
        assert!(parse_world_from_room("1,2,3,4,0").is_err());
        assert!(parse_world_from_room("1,2,3,4,inf").is_err());
    }
}
