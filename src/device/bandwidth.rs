//! The device's copy bandwidth: the ceiling that the fluid step's memory traffic is quoted
//! against, measured in the same run as the step ([`crate::bench`]).
//!
//! A buffer-to-buffer copy (`copy_buffer_to_buffer`, the driver's own copy engine or kernel)
//! of `bytes` between two device buffers, repeated, timed from submission to completion. Each
//! copy reads and writes `bytes`, so the bandwidth counts `2 · bytes` per copy, as the STREAM
//! copy does and as [`crate::lbm::Fluid::bytes_per_update`] counts a step (the populations read
//! once and written once).

use std::time::Instant;

use super::{Context, DeviceError};

/// The measured copy bandwidth.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct CopyBandwidth {
    /// Bytes per copied buffer.
    pub bytes: u64,
    /// Best repetition, GB/s (read plus write).
    pub gbs: f64,
    /// Median repetition, GB/s.
    pub gbs_median: f64,
}

/// Copies per repetition are chosen so that one repetition lasts about this long.
const REPETITION_SECONDS: f64 = 0.2;

/// Measures the copy bandwidth of `ctx`'s device with buffers of `bytes` (rounded down to a
/// multiple of 4, capped by the device's buffer limit): best and median of `reps`
/// repetitions, after a warm-up copy.
///
/// # Errors
/// The device cannot make the buffers, or fails.
pub fn copy_bandwidth(ctx: &Context, bytes: u64, reps: usize) -> Result<CopyBandwidth, DeviceError> {
    let bytes = bytes.min(ctx.limits.max_buffer_size).max(4) & !3;
    let scope = ctx.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let make = |label| {
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: bytes,
            usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    };
    let (src, dst) = (make("copy source"), make("copy destination"));
    if let Some(e) = pollster::block_on(scope.pop()) {
        return Err(DeviceError::Wgpu(format!("copy buffers of {bytes} bytes: {e}")));
    }
    let copies = |n: u32| -> Result<f64, DeviceError> {
        let mut enc = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        for k in 0..n {
            // Alternate the direction so that no copy can be skipped as a repeat.
            let (a, b) = if k % 2 == 0 { (&src, &dst) } else { (&dst, &src) };
            enc.copy_buffer_to_buffer(a, 0, b, 0, bytes);
        }
        let t = Instant::now();
        ctx.queue.submit([enc.finish()]);
        ctx.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| DeviceError::Wgpu(e.to_string()))?;
        Ok(t.elapsed().as_secs_f64())
    };
    let once = copies(1)?.max(1e-7);
    let n = ((REPETITION_SECONDS / once) as u32).clamp(2, 10_000);
    let mut rates = Vec::with_capacity(reps.max(1));
    for _ in 0..reps.max(1) {
        let t = copies(n)?;
        rates.push(2.0 * bytes as f64 * f64::from(n) / t / 1e9);
    }
    rates.sort_by(f64::total_cmp);
    Ok(CopyBandwidth { bytes, gbs: rates[rates.len() - 1], gbs_median: rates[rates.len() / 2] })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The measurement runs and gives a finite, positive bandwidth whose best is at least its
    /// median (on the CPU driver where there is no GPU; its figure is no device's speed).
    #[test]
    fn copy_bandwidth_is_measured() {
        let ctx = Context::new().unwrap_or_else(|e| panic!("the device tests need a Vulkan adapter: {e}"));
        let b = copy_bandwidth(&ctx, 1 << 20, 3).unwrap();
        assert_eq!(b.bytes, 1 << 20);
        assert!(b.gbs.is_finite() && b.gbs > 0.0 && b.gbs >= b.gbs_median, "{b:?}");
    }
}
