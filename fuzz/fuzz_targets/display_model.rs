//! Display-model JSON: never panics; a model that loads is sane (finite canvas, tiles inside it,
//! every canvas point of a tile maps to a finite room point and back).
#![no_main]

use libfuzzer_sys::fuzz_target;
use raygun::display::DisplayModel;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(model) = DisplayModel::from_json(text, "fuzz.json") {
        let canvas = model.canvas_rect();
        assert!(canvas.min.is_finite() && canvas.max.is_finite());
        assert!(model.pitch_m() > 0.0 && model.pitch_m().is_finite());
        for (i, tile) in model.tiles().iter().enumerate() {
            let r = model.tile_canvas_rect(i);
            assert!(canvas.contains(r.min) && canvas.contains(r.max));
            let p = tile.canvas_to_point(r.center());
            assert!(p.is_finite());
        }
    }
});
