//! The model's sun per vertex (step 2b of DESIGN.md "One frame", right after the shadow pass): a
//! compute pass (shaders/vertex_sun.wgsl) that looks the shadow map up once per vertex of the
//! drawn level, with the lookup the frame's method uses per pixel, into a buffer the model pass
//! binds as a vertex attribute (model.wgsl `VertexIn.sun`). The sun's visibility at a surface
//! does not depend on the view, so it runs only when the shadow map changes (or the lookup
//! does), not every frame, and not while the map is drawn on consecutive frames (a moving map:
//! the compositor draws those per pixel); the model pass then interpolates it instead of
//! sampling the map per pixel on the meshes whose triangles are small on screen
//! ([`crate::render::passes::model::MAX_SUN_EDGE_PX`]), and it runs for those meshes alone. A second entry point in the same pass
//! (`split`) sorts the level's triangles into those whose sunlit vertices agree, drawn with the
//! sun interpolated, and those a shadow's edge crosses, drawn with the per-pixel lookup (two
//! indexed indirect draws per mesh), leaving out those whose backs the camera sees
//! ([`SPLIT_CULL_MARGIN`]); so the pass also runs again when the camera moves past that margin.

use super::model::ModelGpu;
use crate::gpu::build;
use crate::render::LightingMethod;
use crate::render::pipelines::Pipelines;
use crate::render::shaders::{Technique, source};
use crate::scene::lod::IndexRange;
use wgpu::SamplerBindingType::{Comparison, NonFiltering};
use wgpu::ShaderStages;

/// Invocations per workgroup (shaders/vertex_sun.wgsl `@workgroup_size`).
const WORKGROUP: u32 = 64;

/// How far the camera may move (times its distance to the model's origin when the split ran)
/// before the split must run again: the split leaves out the triangles whose plane has the
/// camera behind it by more than this much (shaders/vertex_sun.wgsl `may_face_camera`), which
/// no camera within that distance sees from the front. The model pass culls their back faces
/// anyway; left out of the lists they cost neither the vertex stage nor the raster's set-up.
/// Over the triangles whose back the camera sees, 5 % keeps those within about 3° of edge-on
/// from where the camera is (where it is far from the model), and the split runs again once the
/// camera has moved 5 % of its distance: a hand-held phone's shake does not move it, walking
/// around the model does every few steps.
pub const SPLIT_CULL_MARGIN: f32 = 0.05;

/// Whether the split run with the camera at `split_camera` holds for the camera at `camera`,
/// the model's origin at `origin` (world; the model not moved since): the camera moved less
/// than [`SPLIT_CULL_MARGIN`] times its distance to the origin then, with a thousandth of that
/// spared for the shader's rounding.
pub fn split_holds(split_camera: glam::Vec3, origin: glam::Vec3, camera: glam::Vec3) -> bool {
    camera.distance(split_camera) < 0.999 * SPLIT_CULL_MARGIN * split_camera.distance(origin)
}

/// How a method looks the sun up (the override `SOFT` of the compute shader).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SunLookup {
    /// frame.wgsl `sun_visibility_soft` (PCSS): sh9-ggx.
    Soft,
    /// frame.wgsl `sun_visibility` (2×2 comparison taps): the other opaque methods.
    Filtered,
}

impl SunLookup {
    /// The lookup `method`'s shading uses, None for the refracting methods (no sun shadow).
    pub fn of(method: LightingMethod) -> Option<SunLookup> {
        match method {
            LightingMethod::Sh9Ggx => Some(SunLookup::Soft),
            LightingMethod::CubeRefraction | LightingMethod::LiveRefraction => None,
            _ => Some(SunLookup::Filtered),
        }
    }
}

/// The compute pipelines (one per [`SunLookup`]) and their layouts.
pub struct VertexSunPipelines {
    /// Bind group 0: frame, instance and light uniforms, a shadow map, its comparison and
    /// gather samplers.
    pub layout: wgpu::BindGroupLayout,
    /// Bind group 1, one per mesh and level: the mesh's vertices, the level's vertex indices,
    /// the visibility per vertex.
    pub mesh_layout: wgpu::BindGroupLayout,
    soft: wgpu::ComputePipeline,
    filtered: wgpu::ComputePipeline,
    /// The split of a level's triangles into those whose vertices agree and the others
    /// (shaders/vertex_sun.wgsl `split`).
    split: wgpu::ComputePipeline,
}

/// The compute pipelines, built once per device with the other passes' ([`Pipelines`]).
pub fn pipelines(device: &wgpu::Device) -> VertexSunPipelines {
    let cs = ShaderStages::COMPUTE;
    let layout = build::layout(
        device,
        "vertex sun",
        &[
            build::uniform(0, cs),
            build::uniform(1, cs),
            build::uniform(2, cs),
            build::depth_texture_entry(3, cs),
            build::sampler_entry(4, cs, Comparison),
            build::sampler_entry(5, cs, NonFiltering),
        ],
    );
    let mesh_layout = build::layout(
        device,
        "vertex sun mesh",
        &[
            build::storage(0, cs, true),
            build::storage(1, cs, true),
            build::storage(2, cs, false),
            build::storage(3, cs, true),
            build::storage(4, cs, false),
            build::storage(5, cs, false),
            build::uniform(6, cs),
        ],
    );
    let module = build::shader(device, "vertex sun", source(Technique::VertexSun));
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("vertex sun"),
        bind_group_layouts: &[Some(&layout), Some(&mesh_layout)],
        immediate_size: 0,
    });
    let make = |(label, entry, soft): (&str, &str, bool)| {
        let constants = [("SOFT", if soft { 1.0 } else { 0.0 })];
        device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(label),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some(entry),
            compilation_options: wgpu::PipelineCompilationOptions { constants: &constants, ..Default::default() },
            cache: None,
        })
    };
    VertexSunPipelines {
        layout,
        mesh_layout,
        soft: make(("vertex sun (soft)", "main", true)),
        filtered: make(("vertex sun (filtered)", "main", false)),
        split: make(("vertex sun split", "split", true)),
    }
}

/// The vertex indices of each level of a mesh, each once, in one buffer: level `l`'s list
/// starts at `offsets[l]` bytes (a multiple of `align`, the device's storage-offset alignment)
/// and holds `counts[l]` indices, followed by at least one more entry (a level without vertices
/// still binds four bytes). From the levels' triangle lists (`indices[range]`).
pub fn level_vertex_lists(indices: &[u32], ranges: &[IndexRange], vertex_count: usize, align: u64) -> (Vec<u32>, Vec<u64>, Vec<u32>) {
    let per_align = (align / 4).max(1) as usize;
    let (mut all, mut offsets, mut counts) = (Vec::new(), Vec::new(), Vec::new());
    let mut seen = vec![false; vertex_count];
    for &IndexRange { first, count } in ranges {
        all.resize(all.len().div_ceil(per_align) * per_align, 0);
        offsets.push(all.len() as u64 * 4);
        seen.fill(false);
        let start = all.len();
        for &v in &indices[first as usize..(first + count) as usize] {
            if let Some(s) = seen.get_mut(v as usize).filter(|s| !**s) {
                *s = true;
                all.push(v);
            }
        }
        counts.push((all.len() - start) as u32);
    }
    all.push(0);
    (all, offsets, counts)
}

/// The pass: its pipelines and bind group 0 per shadow map.
pub struct VertexSunPass {
    soft: wgpu::ComputePipeline,
    filtered: wgpu::ComputePipeline,
    split: wgpu::ComputePipeline,
    /// Bind group 0 per shadow map (in the order of `ShadowPass::maps`).
    bind_groups: Vec<wgpu::BindGroup>,
}

impl VertexSunPass {
    /// The pass reading the frame, instance and light uniforms and each of `shadow_maps`.
    pub fn new(
        device: &wgpu::Device,
        pipelines: &Pipelines,
        (frame, instance, light): (&wgpu::Buffer, &wgpu::Buffer, &wgpu::Buffer),
        shadow_maps: &[wgpu::TextureView],
    ) -> VertexSunPass {
        use wgpu::BindingResource::{Sampler, TextureView};
        let p = &pipelines.vertex_sun;
        let bind_groups = shadow_maps
            .iter()
            .map(|map| {
                build::bind_group(
                    device,
                    "vertex sun",
                    &p.layout,
                    &[
                        frame.as_entire_binding(),
                        instance.as_entire_binding(),
                        light.as_entire_binding(),
                        TextureView(map),
                        Sampler(&pipelines.shadow_sampler),
                        Sampler(&pipelines.shadow_gather_sampler),
                    ],
                )
            })
            .collect();
        VertexSunPass { soft: p.soft.clone(), filtered: p.filtered.clone(), split: p.split.clone(), bind_groups }
    }

    /// Look the sun up at every vertex of `model`'s level `level` in shadow map `shadow_index`
    /// with `lookup`, into the visibility buffer of each mesh `chosen` names (in the order of the
    /// model's meshes: those the model pass draws per vertex this frame,
    /// [`ModelGpu::sun_groups`]); then split those meshes' triangles of that level into those
    /// whose sunlit vertices agree and the others, with the counts in their indirect draws
    /// (which [`ModelGpu::reset_split_draws`] must have zeroed for this submission). The lookup
    /// and the split are two compute passes with their own `timestamps`; nothing is recorded
    /// when no mesh is chosen.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        (model, chosen): (&ModelGpu, &[bool]),
        (level, shadow_index, lookup): (usize, usize, SunLookup),
        timestamps: [Option<wgpu::ComputePassTimestampWrites<'_>>; 2],
    ) {
        let Some(group) = self.bind_groups.get(shadow_index) else { return };
        if model.sun_groups(level, chosen).next().is_none() {
            return;
        }
        let [lookup_ts, split_ts] = timestamps;
        {
            let mut pass =
                encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("vertex sun"), timestamp_writes: lookup_ts });
            pass.set_pipeline(if lookup == SunLookup::Soft { &self.soft } else { &self.filtered });
            pass.set_bind_group(0, group, &[]);
            for (mesh_group, count, _) in model.sun_groups(level, chosen) {
                if count > 0 {
                    pass.set_bind_group(1, mesh_group, &[]);
                    pass.dispatch_workgroups(count.div_ceil(WORKGROUP), 1, 1);
                }
            }
        }
        let mut pass =
            encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("vertex sun split"), timestamp_writes: split_ts });
        pass.set_pipeline(&self.split);
        pass.set_bind_group(0, group, &[]);
        for (mesh_group, _, triangles) in model.sun_groups(level, chosen) {
            if triangles > 0 {
                pass.set_bind_group(1, mesh_group, &[]);
                pass.dispatch_workgroups(triangles.div_ceil(WORKGROUP), 1, 1);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_split_holds_while_the_camera_stays_within_its_margin() {
        use glam::Vec3;
        let origin = Vec3::new(8.5, -3.0, 0.0);
        // 10 m from the model's origin: the split holds within 0.5 m (less the thousandth).
        let at = origin + Vec3::new(-10.0, 0.0, 0.0);
        assert!(split_holds(at, origin, at));
        assert!(split_holds(at, origin, at + Vec3::new(0.0, 0.49, 0.0)));
        assert!(!split_holds(at, origin, at + Vec3::new(0.0, 0.0, 0.5)));
        // 0.485 m and 0.502 m along a diagonal.
        assert!(split_holds(at, origin, at + Vec3::splat(0.28)));
        assert!(!split_holds(at, origin, at + Vec3::splat(0.29)));
        // Twice as far, twice the room; at the origin itself, none.
        let far = origin + Vec3::new(-20.0, 0.0, 0.0);
        assert!(split_holds(far, origin, far + Vec3::new(0.0, 0.9, 0.0)));
        assert!(!split_holds(origin, origin, origin));
    }

    #[test]
    fn each_level_lists_its_vertices_once_at_aligned_offsets() {
        // Level 0: two triangles over vertices 0-3; level 1: one triangle over 0, 2, 3.
        let indices = [0, 1, 2, 2, 1, 3, 0, 2, 3];
        let range = |first, count| IndexRange { first, count };
        let (all, offsets, counts) = level_vertex_lists(&indices, &[range(0, 6), range(6, 3)], 4, 16);
        assert_eq!(offsets, [0, 16]);
        assert_eq!(counts, [4, 3]);
        assert_eq!(&all[..4], &[0, 1, 2, 3]);
        assert_eq!(&all[4..7], &[0, 2, 3]);
        // An index past the vertices is left out (the mesh loaders reject those before).
        let (all, _, counts) = level_vertex_lists(&[0, 1, 9], &[range(0, 3)], 2, 256);
        assert_eq!(counts, [2]);
        assert_eq!(all.len(), 3);
    }
}
