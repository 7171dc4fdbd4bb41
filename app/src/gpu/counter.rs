//! What a render pass drew, from pipeline-statistics queries: the triangles that left clipping
//! and the fragment-shader invocations, as the driver counts them. Lavapipe counts 16
//! invocations for every 4×4 block a triangle covers part of, before the depth test (a full
//! 960×640 triangle: 619,520), which is the work its rasteriser does; other drivers count
//! their own way. Unlike timestamps, the counts do not swing with the machine's load, so two
//! builds' passes can be compared on a busy machine.

use super::Gpu;
use super::readback::QueryResults;
use anyhow::Result;

/// The pipeline statistics each slot records, in the order the query writes them.
const STATISTICS: wgpu::PipelineStatisticsTypes =
    wgpu::PipelineStatisticsTypes::CLIPPER_PRIMITIVES_OUT.union(wgpu::PipelineStatisticsTypes::FRAGMENT_SHADER_INVOCATIONS);

/// One pass's counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct PassCount {
    /// Primitives out of clipping: triangles, after those outside the view are dropped and those
    /// across its edges cut (a full-screen triangle: 3 on lavapipe); back faces are culled later.
    pub triangles: u64,
    /// Fragment-shader invocations.
    pub fragments: u64,
}

/// Pipeline-statistics queries for up to `capacity` render passes, one slot each.
pub struct PassCounter {
    queries: QueryResults,
    capacity: u32,
}

/// Bytes between two slots' results in the resolve buffer (each resolve's offset is aligned).
const STRIDE: u64 = wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT;

impl PassCounter {
    /// `None` when the device has no pipeline-statistics queries (or `capacity` is 0).
    pub fn new(gpu: &Gpu, capacity: u32) -> Option<PassCounter> {
        if !gpu.pipeline_statistics || capacity == 0 {
            return None;
        }
        let ty = wgpu::QueryType::PipelineStatistics(STATISTICS);
        let queries = QueryResults::new(gpu, "pass counter", ty, capacity, u64::from(capacity) * STRIDE);
        Some(PassCounter { queries, capacity })
    }

    /// Count what `draw` records into `pass` in `slot` (uncounted beyond the capacity).
    pub fn count<T>(&self, pass: &mut wgpu::RenderPass<'_>, slot: u32, draw: impl FnOnce(&mut wgpu::RenderPass<'_>) -> T) -> T {
        if slot >= self.capacity {
            return draw(pass);
        }
        pass.begin_pipeline_statistics_query(&self.queries.query_set, slot);
        let drawn = draw(pass);
        pass.end_pipeline_statistics_query();
        drawn
    }

    /// Record the resolve of `slots` (after the passes, before submit): those counted in this
    /// submission, each into its own place.
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder, slots: &[u32]) {
        for &slot in slots.iter().filter(|&&s| s < self.capacity) {
            self.queries.resolve(encoder, slot..slot + 1, u64::from(slot) * STRIDE);
        }
        self.queries.copy_out(encoder, u64::from(self.capacity) * STRIDE);
    }

    /// The count of each slot (after the submission completed; what a slot not resolved in it
    /// holds is stale).
    pub fn read(&self, gpu: &Gpu) -> Result<Vec<PassCount>> {
        let values = self.queries.read(gpu)?;
        Ok(values.chunks_exact((STRIDE / 8) as usize).map(|v| PassCount { triangles: v[0], fragments: v[1] }).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::build;

    /// A 16×16 target and the triangle with corners at pixels' corners (0, 0), (16, 0) and
    /// (0, 16), then nothing: the triangle covers the pixels whose centres (i + ½, j + ½) have
    /// i + j ≤ 14, 120 of them, with 16 more on its long edge that the top-left rule gives to it
    /// or not. In 4×4 blocks it touches those with bx + by ≤ 3: 10 blocks, 160 lanes. A driver
    /// counts one way or the other (lavapipe: per block).
    #[test]
    fn counts_the_triangles_and_fragments_of_each_counted_pass() {
        let gpu = crate::gpu::tests::gpu();
        let Some(counter) = PassCounter::new(gpu, 2) else {
            assert!(!gpu.pipeline_statistics);
            return;
        };
        let source = "
            @vertex fn vs_main(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
                let corners = array(vec2<f32>(-1.0, 1.0), vec2<f32>(1.0, 1.0), vec2<f32>(-1.0, -1.0));
                return vec4<f32>(corners[i], 0.0, 1.0);
            }
            @fragment fn fs_main() -> @location(0) vec4<f32> { return vec4<f32>(1.0); }";
        let module = build::shader(&gpu.device, "counter test", source.into());
        let format = wgpu::TextureFormat::Rgba8Unorm;
        let pipeline = build::render_pipeline(&gpu.device, build::PipelineSpec::full_screen("counter test", &module, &[], format));
        let target = build::texture(&gpu.device, "counter test", (16, 16, 1), format, 1, wgpu::TextureUsages::RENDER_ATTACHMENT);
        let view = target.create_view(&Default::default());
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        {
            let mut pass = build::clear_pass(&mut encoder, "counted", &view, None);
            pass.set_pipeline(&pipeline);
            counter.count(&mut pass, 0, |pass| pass.draw(0..3, 0..1));
            counter.count(&mut pass, 1, |_| ());
        }
        counter.resolve(&mut encoder, &[0, 1]);
        gpu.queue.submit([encoder.finish()]);
        let counts = counter.read(gpu).unwrap();
        assert_eq!(counts[0].triangles, 1, "{counts:?}");
        assert!([120, 136, 160].contains(&counts[0].fragments), "{counts:?}");
        assert_eq!(counts[1], PassCount::default(), "an empty pass draws nothing");
    }
}
