//! GPU DGI kernel against its CPU twin (f64) on a wall generated in code.

use glam::DVec3;
use raygun::display::DisplayModel;
use raygun::gpu::GpuContext;
use raygun::roi::cone::Cone;
use raygun::roi::dgi::{DgiParams, Guide, Metric, Roi, Surface, compute_cpu};
use raygun::roi::gpu::DgiKernel;

/// Three columns of 1000×600 px at 1 mm pitch, hinged at their edges with `yaw_deg` between
/// neighbours, curving towards a viewer on +Z; the centre column in z = 0, centred at the origin.
fn curved_wall(yaw_deg: f64) -> Surface {
    let json = format!(
        r#"{{"name": "test wall", "notes": "built in tests/dgi_twins.rs",
            "generator": {{"columns": 3, "rows": 1, "resolution": [1000, 600],
            "active_size": [1.0, 0.6],
            "bezel": {{"left": 0.0, "right": 0.0, "top": 0.0, "bottom": 0.0}},
            "yaw_step_deg": {yaw_deg}, "center": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0],
            "up": [0.0, 1.0, 0.0]}}}}"#
    );
    Surface::from_model(&DisplayModel::from_json(&json, "curved_wall").unwrap())
}

/// Raw-distance agreement: |d_GPU − d_CPU| ≤ RAW_ABS_PX + RAW_REL · d_CPU. The kernel's pixel
/// offsets are exact to f32 rounding of the local offset (≤ ~1e-7 × 3000 px here), the solvers
/// reach ~1e-6 of their scale in f32 (tests/display/ellipse_hard_cases.rs), and far distances grow
/// with the conic's size; measured worst on lavapipe: ~1e-4 relative.
const RAW_ABS_PX: f64 = 2e-3;
const RAW_REL: f64 = 5e-4;

#[test]
fn gpu_matches_cpu_twin_on_ellipses_hyperbolas_and_parabolas() {
    let ctx = GpuContext::for_tests();
    let kernel = DgiKernel::new(&ctx);
    let surface = curved_wall(30.0);
    let params = DgiParams {
        width: 300,
        height: 60,
        falloff_px: None,
    };
    let poses = [
        (
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(0.0, 0.0, -1.0),
            20.0,
            20.0,
        ),
        (
            DVec3::new(0.2, 0.1, 0.8),
            DVec3::new(0.6, 0.0, -1.0),
            60.0,
            40.0,
        ),
        (
            DVec3::new(-0.4, 0.0, 0.3),
            DVec3::new(1.0, 0.0, -0.35),
            60.0,
            60.0,
        ),
        // 60° off the centre column's normal with a 60° cone: a generator parallel to it.
        (
            DVec3::new(-0.9, 0.0, 0.6),
            DVec3::new(60f64.to_radians().sin(), 0.0, -60f64.to_radians().cos()),
            60.0,
            60.0,
        ),
    ];
    let mut kinds = std::collections::BTreeSet::new();
    for (o, d, fh, fv) in poses {
        let cone = Cone::from_pose(o, d, DVec3::Y, fh, fv).unwrap();
        if let Guide::Pieces(pieces) =
            Guide::new(&surface, &Roi::Cone(cone), Metric::Exact).unwrap()
        {
            for p in pieces {
                kinds.insert(
                    format!("{:?}", p.conic.kind)
                        .split([' ', '{'])
                        .next()
                        .unwrap()
                        .to_owned(),
                );
            }
        }
        for metric in [Metric::Exact, Metric::Ellipse, Metric::Angular] {
            let guide = Guide::new(&surface, &Roi::Cone(cone), metric).unwrap();
            let cpu = compute_cpu(&surface, &guide, &params);
            let gpu = kernel.compute(&ctx, &surface, &guide, &params).unwrap();
            for (i, (c, g)) in cpu.iter().zip(&gpu).enumerate() {
                let (c, g) = (f64::from(*c), f64::from(*g));
                assert!(
                    (c - g).abs() <= RAW_ABS_PX + RAW_REL * c,
                    "{metric:?} from {o}: pixel {i}: CPU {c} GPU {g}"
                );
            }
        }
    }
    // The poses were chosen to exercise every solver path of the kernel.
    for kind in ["Ellipse", "Hyperbola", "Parabola"] {
        assert!(kinds.contains(kind), "no {kind} among {kinds:?}");
    }
}
