//! `raygun display outputs`: the grid helper writes a map that loads back against its model,
//! says what it wrote, and refuses a grid the model's tiles do not form.

use raygun::display::DisplayModel;
use raygun::display::outputs::OutputMap;

use crate::support::{raygun, tmp_dir};

#[test]
fn writes_hornet_one_desktop_per_column_and_it_loads_back() {
    let dir = tmp_dir("outputs-columns");
    let out = dir.join("walls.json");
    let o = raygun(&[
        "display",
        "outputs",
        "hornet",
        "--grid",
        "7x5",
        "--per-desktop",
        "1x5",
        "--out",
        out.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        stdout.contains("7 desktop(s) showing 35 of the 35 tiles of HORNET"),
        "{stdout}"
    );
    assert!(
        stdout.contains("rank6: 1920×5400: c6r0 c6r1 c6r2 c6r3 c6r4"),
        "{stdout}"
    );
    let model = DisplayModel::open("hornet").unwrap().0;
    let map = OutputMap::load(&out, &model).unwrap();
    assert_eq!(map, OutputMap::grid(&model, [7, 5], [1, 5]).unwrap());
    // No temporary left beside it.
    assert_eq!(std::fs::read_dir(&*dir).unwrap().count(), 1);
}

#[test]
fn without_a_grid_it_writes_the_one_desktop_default() {
    let dir = tmp_dir("outputs-default");
    let out = dir.join("wall.json");
    let o = raygun(&[
        "display",
        "outputs",
        "hornet",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let model = DisplayModel::open("hornet").unwrap().0;
    let map = OutputMap::load(&out, &model).unwrap();
    assert_eq!(map, OutputMap::default_for(&model).unwrap());
}

#[test]
fn a_grid_the_model_does_not_form_is_an_error_and_writes_nothing() {
    let dir = tmp_dir("outputs-bad-grid");
    let out = dir.join("walls.json");
    let o = raygun(&[
        "display",
        "outputs",
        "hornet",
        "--grid",
        "5x7",
        "--out",
        out.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        stderr.contains("tile \"c5r0\" is at column 5, row 0: outside the 5x7 grid"),
        "{stderr}"
    );
    assert!(!out.exists());
    let o = raygun(&[
        "display",
        "outputs",
        "hornet",
        "--grid",
        "7by5",
        "--out",
        out.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(stderr.contains("expected COLSxROWS"), "{stderr}");
}
