//! `raygun bench readback`: what a picture's read-back costs. Every viewer picture and every
//! `bench all` iteration reads the accumulation (16 bytes a pixel) back from the GPU; this
//! times that read-back of a `size` buffer through a fresh mappable buffer (what every
//! read-back did before [`GpuContext`] kept them) and through a kept one, side by side in each
//! round, and checks that both return the buffer's bytes.

use std::time::Instant;

use serde::Serialize;
use wgpu::util::DeviceExt;

use crate::gpu::{GpuContext, GpuError};

/// One way of reading back, over the rounds.
#[derive(Clone, Debug, Serialize)]
pub struct ReadbackRow {
    pub way: &'static str,
    pub ms_min: f64,
    pub ms_median: f64,
    /// Bytes per second at the median, in GB/s (10⁹).
    pub gb_per_s: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct ReadbackReport {
    pub device: String,
    pub size: [u32; 2],
    pub bytes: u64,
    pub rounds: u32,
    pub rows: Vec<ReadbackRow>,
}

#[derive(Debug, thiserror::Error)]
pub enum ReadbackBenchError {
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error("the read-back through a {way} buffer returned other bytes than the buffer holds")]
    Differs { way: &'static str },
    #[error(
        "--size {w},{h}: {bytes} bytes at 16 a pixel is more than one buffer may hold here ({max})"
    )]
    TooLarge {
        w: u32,
        h: u32,
        bytes: u64,
        max: u64,
    },
}

/// Times `rounds` read-backs each way of a `size` accumulation-sized buffer.
pub fn run(
    ctx: &GpuContext,
    size: [u32; 2],
    rounds: u32,
) -> Result<ReadbackReport, ReadbackBenchError> {
    let [w, h] = size;
    let bytes = 16 * u64::from(w) * u64::from(h);
    if bytes > ctx.limits.max_buffer_size {
        return Err(ReadbackBenchError::TooLarge {
            w,
            h,
            bytes,
            max: ctx.limits.max_buffer_size,
        });
    }
    let data: Vec<u32> = (0..bytes / 4)
        .map(|i| (i as u32).wrapping_mul(2_654_435_761))
        .collect();
    let src = ctx
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("bench readback source"),
            contents: bytemuck::cast_slice(&data),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        });
    let (mut fresh, mut kept) = (Vec::new(), Vec::new());
    for round in 0..rounds.max(1) {
        ctx.clear_staging();
        let t = Instant::now();
        let a: Vec<u32> = ctx.read_buffer(&src)?;
        fresh.push(t.elapsed().as_secs_f64() * 1e3);
        let t = Instant::now();
        let b: Vec<u32> = ctx.read_buffer(&src)?;
        kept.push(t.elapsed().as_secs_f64() * 1e3);
        if round == 0 {
            if a != data {
                return Err(ReadbackBenchError::Differs { way: "fresh" });
            }
            if b != data {
                return Err(ReadbackBenchError::Differs { way: "kept" });
            }
        }
    }
    let row = |way, ms: Vec<f64>| {
        let median = crate::bench::median(ms.clone());
        ReadbackRow {
            way,
            ms_min: ms.iter().copied().fold(f64::INFINITY, f64::min),
            ms_median: median,
            gb_per_s: bytes as f64 / (median * 1e-3) / 1e9,
        }
    };
    Ok(ReadbackReport {
        device: ctx.describe(),
        size,
        bytes,
        rounds: rounds.max(1),
        rows: vec![
            row("fresh mappable buffer (before)", fresh),
            row("kept mappable buffer", kept),
        ],
    })
}

/// The report as Markdown, with the kept way's median over the fresh one's.
#[must_use]
pub fn markdown(r: &ReadbackReport) -> String {
    let mut s = format!(
        "Read-back of a {}×{} accumulation ({:.1} MB, 16 bytes a pixel), {} rounds, both ways in each; device: {}\n\n| way | ms min | ms median | GB/s (median) |\n|---|---|---|---|\n",
        r.size[0],
        r.size[1],
        r.bytes as f64 / 1e6,
        r.rounds,
        r.device
    );
    for row in &r.rows {
        s += &format!(
            "| {} | {:.3} | {:.3} | {:.2} |\n",
            row.way, row.ms_min, row.ms_median, row.gb_per_s
        );
    }
    if let [fresh, kept] = &r.rows[..] {
        s += &format!(
            "\nKept ÷ fresh (medians): ×{:.3}\n",
            kept.ms_median / fresh.ms_median
        );
    }
    s
}

#[cfg(test)]
mod tests {
    /// Both ways return the buffer's bytes (checked inside `run`) and the table names both.
    #[test]
    fn both_ways_read_the_same_bytes_and_are_reported() {
        let ctx = crate::gpu::GpuContext::for_tests();
        let r = super::run(&ctx, [64, 32], 3).unwrap();
        assert_eq!(r.bytes, 64 * 32 * 16);
        assert_eq!(r.rows.len(), 2);
        assert!(
            r.rows
                .iter()
                .all(|row| row.ms_min > 0.0 && row.ms_min <= row.ms_median)
        );
        let md = super::markdown(&r);
        assert!(md.contains("| fresh mappable buffer (before) |"), "{md}");
        assert!(md.contains("Kept ÷ fresh"), "{md}");
    }
}
