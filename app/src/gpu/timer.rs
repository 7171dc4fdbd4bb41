//! GPU time of passes with timestamp queries: `slot` i holds a (begin, end) pair. A slot may span
//! several passes: the first writes its begin, the last its end.

use super::Gpu;
use super::readback::QueryResults;
use anyhow::Result;

/// Pairs of GPU timestamps (begin, end) for up to `capacity` slots.
pub struct GpuTimer {
    queries: QueryResults,
    capacity: u32,
}

impl GpuTimer {
    /// `None` when the device has no timestamp queries (or `capacity` is 0).
    pub fn new(gpu: &Gpu, capacity: u32) -> Option<GpuTimer> {
        if !gpu.timestamps || capacity == 0 {
            return None;
        }
        let count = capacity * 2;
        let queries = QueryResults::new(gpu, "timer", wgpu::QueryType::Timestamp, count, u64::from(count) * 8);
        Some(GpuTimer { queries, capacity })
    }

    fn indices(&self, slot: u32, begin: bool, end: bool) -> Option<(Option<u32>, Option<u32>)> {
        (slot < self.capacity && (begin || end)).then(|| (begin.then_some(slot * 2), end.then_some(slot * 2 + 1)))
    }

    /// Timestamp writes for a render pass: the begin and/or end of `slot`.
    pub fn render_pass(&self, slot: u32, begin: bool, end: bool) -> Option<wgpu::RenderPassTimestampWrites<'_>> {
        self.indices(slot, begin, end).map(|(b, e)| wgpu::RenderPassTimestampWrites {
            query_set: &self.queries.query_set,
            beginning_of_pass_write_index: b,
            end_of_pass_write_index: e,
        })
    }

    /// Timestamp writes for a compute pass: the begin and/or end of `slot`.
    pub fn compute_pass(&self, slot: u32, begin: bool, end: bool) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        self.indices(slot, begin, end).map(|(b, e)| wgpu::ComputePassTimestampWrites {
            query_set: &self.queries.query_set,
            beginning_of_pass_write_index: b,
            end_of_pass_write_index: e,
        })
    }

    /// Record the resolve of the first `used` slots (after the passes, before submit).
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder, used: u32) {
        let used = used.min(self.capacity);
        if used > 0 {
            self.queries.resolve(encoder, 0..used * 2, 0);
            self.queries.copy_out(encoder, u64::from(used) * 16);
        }
    }

    /// Milliseconds of each of the first `used` slots (after the submission completed).
    pub fn read_ms(&self, gpu: &Gpu, used: u32) -> Result<Vec<f64>> {
        let (ticks, period_ns) = self.read_ticks(gpu)?;
        Ok((0..used.min(self.capacity) as usize).map(|i| ticks_to_ms(ticks[2 * i], ticks[2 * i + 1], period_ns)).collect())
    }

    /// The raw timestamps (slot i's begin at 2i, its end at 2i + 1) and nanoseconds per tick, for
    /// spans between the ends of consecutive passes (after the submission completed).
    pub fn read_ticks(&self, gpu: &Gpu) -> Result<(Vec<u64>, f64)> {
        Ok((self.queries.read(gpu)?, f64::from(gpu.queue.get_timestamp_period())))
    }
}

/// Milliseconds between two timestamps of `period_ns` nanoseconds per tick (0 if they run
/// backwards, which some drivers do across passes).
pub fn ticks_to_ms(begin: u64, end: u64, period_ns: f64) -> f64 {
    end.saturating_sub(begin) as f64 * period_ns * 1e-6
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_convert_to_milliseconds() {
        // 2.5 million ticks of 1 ns = 2.5 ms; 1000 ticks of 83.333 ns (a 12 MHz clock) ≈ 0.0833 ms.
        assert!((ticks_to_ms(10, 2_500_010, 1.0) - 2.5).abs() < 1e-12);
        assert!((ticks_to_ms(0, 1000, 1e9 / 12e6) - 0.083_333).abs() < 1e-6);
        assert_eq!(ticks_to_ms(5, 3, 1.0), 0.0);
    }

    #[test]
    fn slots_span_passes_and_out_of_range_slots_write_nothing() {
        let gpu = super::super::tests::gpu();
        let Some(timer) = GpuTimer::new(gpu, 2) else {
            // Lavapipe has timestamps (DESIGN.md); a device without them gets no timer at all.
            assert!(!gpu.timestamps);
            return;
        };
        let w = timer.render_pass(1, true, false).unwrap();
        assert_eq!((w.beginning_of_pass_write_index, w.end_of_pass_write_index), (Some(2), None));
        let w = timer.compute_pass(0, false, true).unwrap();
        assert_eq!((w.beginning_of_pass_write_index, w.end_of_pass_write_index), (None, Some(1)));
        assert!(timer.render_pass(2, true, true).is_none() && timer.render_pass(0, false, false).is_none());
        assert!(GpuTimer::new(gpu, 0).is_none());
    }
}
