//! `--tile-owners` files: never panic; a file that resolves against HORNET gives every tile one
//! owner below the job's size, and the block map built from it names only those ranks.
#![no_main]

use std::path::Path;
use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use raygun::cluster::owners::{BlockOwners, TileOwners, parse_tile_owners};
use raygun::display::DisplayModel;

fn hornet() -> &'static DisplayModel {
    static M: OnceLock<DisplayModel> = OnceLock::new();
    M.get_or_init(|| DisplayModel::open("hornet").expect("the built-in model").0)
}

fuzz_target!(|data: &[u8]| {
    let Some((&ranks, rest)) = data.split_first() else {
        return;
    };
    let ranks = usize::from(ranks % 40) + 1;
    let Ok(text) = std::str::from_utf8(rest) else {
        return;
    };
    let file = Path::new("fuzz.txt");
    let Ok(lines) = parse_tile_owners(text, file) else {
        return;
    };
    if let Ok(o) = TileOwners::from_lines(&lines, file, hornet(), ranks) {
        assert_eq!(o.ranks.len(), hornet().tiles().len());
        assert!(o.ranks.iter().all(|&r| r < ranks));
        let b = BlockOwners::of_display(hornet(), &o, [64, 26]);
        assert!(b.owner.iter().all(|&r| (r as usize) < ranks));
    }
});
