//! `raygun bench schedule` on a small image: its rows are consistent (the GPU's count equals the
//! twin's, the measured share tracks the expected one, wider cones select more). Speed itself is
//! never asserted.

use crate::walls;

use raygun::bench::schedule::{ScheduleBenchConfig, run};
use raygun::gpu::{Backend, GpuContext};
use raygun::roi::dgi::Surface;
use raygun::schedule::Order;

#[test]
fn schedule_benchmark_rows_agree_across_backends_and_fovs() {
    let surface = Surface::from_model(&walls::hornet());
    let backend = Backend::Gpu(Box::new(GpuContext::for_tests()));
    let config = ScheduleBenchConfig {
        size: [192, 108],
        fovs_deg: vec![10.0, 60.0],
        gpu_reps: 2,
        cpu_reps: 1,
        ..ScheduleBenchConfig::default()
    };
    let report = run(&surface, "HORNET", &backend, &config, |_| {}).unwrap();
    // Per FOV and order: a CPU row, then a GPU row.
    assert_eq!(report.rows.len(), 2 * 2 * 2);
    for pair in report.rows.chunks(2) {
        let (cpu, gpu) = (&pair[0], &pair[1]);
        assert_eq!((cpu.backend, gpu.backend), ("cpu", "gpu"));
        assert_eq!(cpu.count_matches_cpu, None);
        assert_eq!(gpu.count_matches_cpu, Some(true), "{gpu:?}");
        assert_eq!(cpu.share_selected, gpu.share_selected);
        // 20 736 pixels: the share's standard deviation is below sqrt(0.25 / 20 736) = 0.0035.
        assert!(
            (cpu.share_selected - cpu.expected_share).abs() < 5.0 * 0.0035,
            "{cpu:?}"
        );
        assert!(gpu.ms_median > 0.0 && gpu.ms_min <= gpu.ms_median);
    }
    let share = |fov: f64| {
        report
            .rows
            .iter()
            .find(|r| r.fov_deg == fov && r.order == Order::Coherent)
            .unwrap()
            .share_selected
    };
    assert!(
        share(60.0) > 5.0 * share(10.0),
        "{} vs {}",
        share(60.0),
        share(10.0)
    );
    let table = report.to_markdown();
    assert!(table.contains("| 60° | gpu"), "{table}");
}
