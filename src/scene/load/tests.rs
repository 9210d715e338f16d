use glam::{Vec2, Vec3};
use gltf::mesh::Mode;

use super::mesh::{triangle_indices, uv_tangents};

#[test]
fn strips_and_fans_unroll_with_the_specifications_winding() {
    let idx = [0, 1, 2, 3, 4];
    assert_eq!(
        triangle_indices(Mode::TriangleStrip, &idx),
        vec![[0, 1, 2], [1, 3, 2], [2, 3, 4]]
    );
    assert_eq!(
        triangle_indices(Mode::TriangleFan, &idx),
        vec![[1, 2, 0], [2, 3, 0], [3, 4, 0]]
    );
    assert!(triangle_indices(Mode::TriangleStrip, &[0, 1]).is_empty());
    assert_eq!(triangle_indices(Mode::Triangles, &idx), vec![[0, 1, 2]]);
}

#[test]
fn uv_tangents_follow_u_and_sign_v_down() {
    // A quad in the xy plane facing +z, u along +x, v along −y (glTF images: v down).
    let p = [Vec3::ZERO, Vec3::X, Vec3::Y];
    let uv = [
        Vec2::new(0.0, 1.0),
        Vec2::new(1.0, 1.0),
        Vec2::new(0.0, 0.0),
    ];
    let t = uv_tangents(p, uv, [Vec3::Z; 3]);
    for t in t {
        assert!((t.truncate() - Vec3::X).length() < 1e-6, "{t}");
        // B = N × T · w = +y: the normal map's +Y points up the image (decreasing v).
        assert_eq!(t.w, 1.0);
    }
}
