//! Output maps: never panic; a map that loads against HORNET shows each tile at most once, at its
//! native size, inside its desktop, without overlaps, and writes back to the same map.
#![no_main]

use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use raygun::display::DisplayModel;
use raygun::display::outputs::OutputMap;

fn hornet() -> &'static DisplayModel {
    static M: OnceLock<DisplayModel> = OnceLock::new();
    M.get_or_init(|| DisplayModel::open("hornet").expect("the built-in model").0)
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let model = hornet();
    if let Ok(map) = OutputMap::from_json(text, "fuzz.json", model) {
        let mut seen = vec![false; model.tiles().len()];
        for d in map.desktops() {
            assert!(!d.tiles.is_empty() && d.size[0] > 0 && d.size[1] > 0);
            for t in &d.tiles {
                let i = model.tile_index(&t.id).expect("a tile of the model");
                assert!(!seen[i]);
                seen[i] = true;
                let [w, h] = model.tiles()[i].resolution().map(i64::from);
                assert_eq!([t.rect[2], t.rect[3]], [w, h]);
                assert!(t.rect[0] >= d.origin[0] && t.rect[0] + w <= d.origin[0] + d.size[0]);
                assert!(t.rect[1] >= d.origin[1] && t.rect[1] + h <= d.origin[1] + d.size[1]);
            }
        }
        let back = OutputMap::from_json(&map.to_json_pretty(), "back.json", model)
            .expect("a written map loads back");
        assert_eq!(back, map);
    }
});
