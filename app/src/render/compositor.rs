//! The compositor: the passes of one frame at one output size, and the frame that runs them.
//!
//! Everything is created once (`Compositor::new`, `set_environment`, `set_model`,
//! `set_background`); a frame only writes uniforms (and the camera image) and encodes passes,
//! so per-frame work allocates no GPU resources.

use super::antialiasing::{Antialiasing, FxaaPass};
use super::environment::{self, Environment, EnvironmentTextures};
use super::frame::{
    Detail, FrameContext, FrameData, GroundMesh, GroundRegions, colour_correction, fit_shadow, frame_uniforms, ground_mesh, light_uniforms,
    lod_level, sky_square,
};
use super::layers::{LayerImages, LayerPass, LayerPipelines, LayerTargets};
use super::model_cache::{ModelCache, PreparedModel};
use super::params::{FrameParams, HemispherePriors, Layer};
use super::passes::background::BackgroundPass;
use super::passes::ground::{GroundPass, INVISIBLE_LOSS, RegionCache, sky_loss_per_occlusion};
use super::passes::ground_sun::{self, GroundSunPass};
use super::passes::model::{Culling, ModelGpu, ModelPass};
use super::passes::shadow::ShadowPass;
use super::passes::vertex_sun::{self, SunLookup, VertexSunPass};
use super::pipelines::{LAYER_SAMPLES, Pipelines};
use super::reprojection::{self, Held, Reprojection};
use super::shadow_fit::{self, ShadowDrawn};
use super::supersample;
use super::targets::Targets;
use super::uniforms::{FrameUniforms, InstanceUniforms, LightUniforms};
use crate::gpu::{Gpu, GpuTimer, PassCount, PassCounter, build};
use crate::scene::environment::Equirect;
use crate::scene::{CubeMap, Model, Rgba8Image, occlusion};
use anyhow::{Result, anyhow};
use glam::Vec3;
use std::sync::Arc;
use std::time::Instant;

/// Timer slots: the shadow pass (with the model's sun per vertex after it), and the passes after
/// it; with pass timing on ([`Compositor::set_pass_timing`]) the passes after it one by one
/// instead, and the shadow pass, the vertex sun's lookup and its split each alone.
const SHADOW_SLOT: u32 = 0;
const REST_SLOT: u32 = 1;
const BACKGROUND_SLOT: u32 = 2;
const MODEL_SLOT: u32 = 3;
const GROUND_SLOT: u32 = 4;
const FXAA_SLOT: u32 = 5;
const SUN_LOOKUP_SLOT: u32 = 6;
const SUN_SPLIT_SLOT: u32 = 7;
const GROUND_SUN_SLOT: u32 = 8;
const VERTEX_LIGHT_SLOT: u32 = 9;
const TIMER_SLOTS: u32 = 10;

/// Milliseconds spent in each stage of a render.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Timings {
    /// CPU: writing uniforms and encoding the passes.
    pub encode_ms: f64,
    /// GPU: the frame's passes (timestamp queries: the shadow pass, plus the first later pass's
    /// start to the last pass's end); None if unsupported.
    pub gpu_ms: Option<f64>,
    /// GPU: the shadow pass and the model's sun per vertex after it (None when neither ran or
    /// without timestamp queries).
    pub shadow_gpu_ms: Option<f64>,
    /// CPU wall time from submit until the pixels are in memory.
    pub readback_ms: f64,
    /// GPU: each pass alone, with pass timing on ([`Compositor::set_pass_timing`]; None
    /// otherwise or without timestamp queries).
    pub passes: Option<PassTimes>,
    /// What each composite pass drew, with pass timing on (None otherwise or without
    /// pipeline-statistics queries).
    pub counts: Option<PassCounts>,
    /// The frame composed the last shaded frame's layers through the camera's turn instead of
    /// shading the model and its ground (render::reprojection).
    pub reprojected: bool,
}

/// What each of the composite's passes drew in one frame ([`crate::gpu::PassCounter`]; None: the
/// pass did not run). The ground's count leaves out its ground-sun pass.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct PassCounts {
    pub background: Option<PassCount>,
    pub model: Option<PassCount>,
    pub ground: Option<PassCount>,
}

/// GPU milliseconds of each pass of one frame (None: the pass did not run). With pass timing on
/// the composite's steps are separate render passes, so their sum is a little more than the
/// frame drawn in one pass costs.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct PassTimes {
    /// The shadow pass and the model's sun per vertex after it.
    pub shadow: Option<f64>,
    /// Of `shadow`: the model's sun per vertex, its lookup and its split
    /// (render::passes::vertex_sun), when it ran.
    pub vertex_sun: Option<[f64; 2]>,
    /// The camera image (or the environment seen by the camera) filling the target.
    pub background: Option<f64>,
    pub model: Option<f64>,
    /// The ground pass, with the ground-sun pass when it drew.
    pub ground: Option<f64>,
    pub fxaa: Option<f64>,
}

impl PassTimes {
    /// The passes' sum.
    pub fn total(&self) -> f64 {
        [self.shadow, self.background, self.model, self.ground, self.fxaa].iter().flatten().sum()
    }
}

/// A rendered RGBA8 image (sRGB-encoded; the model layer is premultiplied in linear light).
pub struct Rendered {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<u8>,
    pub timings: Timings,
}

/// GPU state for compositing at one output size.
pub struct Compositor {
    pipelines: std::sync::Arc<Pipelines>,
    /// The size the frame is drawn at: the output's times `supersample`.
    width: u32,
    height: u32,
    /// Samples per side of each output pixel ([`Compositor::supersampled`]).
    supersample: u32,
    /// The `Frame` uniform every pass reads.
    frame_buf: wgpu::Buffer,
    /// The model's transform, read by the shadow and model passes.
    instance_buf: wgpu::Buffer,
    /// The light measured from the environment (`Light`), read by the ground and model passes.
    light_buf: wgpu::Buffer,
    targets: Targets,
    /// The post-process antialiasing pass (with [`Antialiasing::Fxaa`]).
    fxaa: Option<FxaaPass>,
    antialiasing: Antialiasing,
    /// The float layer targets, made by the first `render_layers`.
    layer_targets: Option<LayerTargets>,
    shadow: ShadowPass,
    /// The model's sun per vertex, looked up after the shadow pass draws.
    vertex_sun: VertexSunPass,
    /// What the model's visibility-per-vertex buffers hold (None: nothing known): a frame
    /// whose map, level and lookup are the same, and whose camera the split still holds for
    /// (`split_view`), does not run the pass again.
    vertex_sun_held: Option<VertexSunHeld>,
    /// Per mesh, whether the buffers of `vertex_sun_held` were computed for it (the meshes the
    /// model pass chose to draw per vertex then; the others' buffers hold nothing of use).
    vertex_sun_meshes: Vec<bool>,
    /// The lookup the last prepared frame runs per vertex (None: the pass does not run).
    vertex_sun_run: Option<SunLookup>,
    /// The camera (world) and the model's matrix when the split last ran: it leaves out the
    /// triangles no camera near that one sees the front of (`vertex_sun::split_holds`).
    split_view: Option<(glam::Vec3, glam::Mat4)>,
    background: BackgroundPass,
    ground: GroundPass,
    /// The ground's sun visibility in ground space, drawn from the shadow map when it changes.
    ground_sun: GroundSunPass,
    model_pass: ModelPass,
    env: Option<Environment>,
    /// The environment's textures (made for the first map of a face size, refreshed in place).
    env_textures: Option<EnvironmentTextures>,
    /// How many environments were set (the refreshes counted by the tests).
    environment_writes: usize,
    model: Option<ModelGpu>,
    /// Slot 0: from the first pass's start to the composite pass's end.
    timer: Option<GpuTimer>,
    /// The composite's steps' counts with pass timing on (slot: the step).
    counter: Option<PassCounter>,
    /// Which level of detail it draws: a frame's, a still's or level 0.
    detail: Detail,
    /// Draw the shadow into the largest map whatever the screen allows (a full-shadow reference).
    full_shadow: bool,
    /// The level of detail the last prepared frame drew.
    level: usize,
    /// The shadow map (index into `ShadowPass::sizes`) the last prepared frame drew into.
    shadow_index: usize,
    /// Whether the last prepared frame ran the shadow and ground passes.
    passes_run: PassesRun,
    /// Time each pass alone (the composite's steps as separate render passes): profiling.
    pass_timing: bool,
    /// What each shadow map holds (in the order of `ShadowPass::sizes`; None: nothing yet): a
    /// frame whose shadow would come out the same keeps the map instead of drawing it again.
    shadow_held: Vec<Option<ShadowDrawn>>,
    /// Per shadow map, whether the last frame that sampled it drew it: a map drawn on two such
    /// frames in a row (a sun turning, a model dragged) is moving, and its frames look the sun
    /// up per pixel without the vertex sun's compute until it holds still for a frame.
    shadow_redrawn: Vec<bool>,
    /// The ground's sky visibility the ground pass holds (from the model cache, for the model
    /// matrix without its translation), and how many times one has been uploaded: once per turn
    /// or scale of the model, not per frame.
    ground_sky_uploaded: Option<Arc<occlusion::GroundSky>>,
    ground_sky_updates: usize,
    /// The model's vertices the model pass holds with the sky each one sees
    /// (PreparedModel::vertices_under): rewritten once per turn of the model or new sky.
    model_sky_uploaded: Option<super::model_cache::MeshVertices>,
    /// Cast a new placement's ground rays on the model cache's worker, drawing the previous map
    /// meanwhile (the live view), instead of waiting for them (a composite).
    ground_in_background: bool,
    /// The ground's regions (the shadow's outline, the sky's visible occlusion), computed once
    /// per shadow map drawn and per sky map.
    ground_regions: RegionCache,
    /// The live view's reprojection ([`Compositor::set_reprojection`]; None: every frame shades).
    reprojection: Option<Reprojecting>,
    /// Whether the last prepared frame reprojected, whether it shaded the layers (the shading
    /// compositor's passes ran), and how many frames reprojected and shaded since reprojection
    /// was turned on.
    reprojected: bool,
    shaded_layers: bool,
    reprojection_counts: (usize, usize),
}

/// The live view's reprojection (render::reprojection): the pass that composes the layers into
/// the frame, and the compositor that shades the model and its ground into them, at the frame's
/// size and field of view widened by `reprojection::margin_px` on every side (its own shadow
/// maps, ground and model buffers; the same environment, model and settings, forwarded).
struct Reprojecting {
    pass: Reprojection,
    shader: Box<Compositor>,
}

/// What the model's visibility-per-vertex buffers were computed from: a shadow map (its index
/// and what it holds, which includes the level of detail) and the lookup, with the sun's
/// angular size the soft lookup widens its penumbra by.
#[derive(Clone, Copy, Debug, PartialEq)]
struct VertexSunHeld {
    shadow_index: usize,
    map: ShadowDrawn,
    lookup: SunLookup,
    tan_sun_radius: f32,
}

/// What [`Compositor::frame_data`] works out for a frame: its uniforms, the shadow map it keeps,
/// and the ground's sky map it draws.
type FrameFacts = (FrameData, Option<ShadowDrawn>, Option<Arc<occlusion::GroundSky>>);

/// Which of the optional passes a frame ran.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PassesRun {
    /// The frame samples a shadow map (the model or its shadow is on screen).
    pub shadow: bool,
    /// The shadow pass drew that map this frame: false when the map already held the same
    /// shadow (`shadow_fit::map_still_valid`: same model, transform and level, the sun moved
    /// less than an eighth of a texel) or when there is no sunlight (nothing to shadow).
    pub shadow_drawn: bool,
    /// The model's sun per vertex was looked up this frame (render::passes::vertex_sun): after
    /// the shadow pass drew (unless the last frame that sampled that map drew it too: a moving
    /// map is looked up per pixel), or when the map, level, lookup or meshes the buffers hold
    /// are not the frame's; never while they hold what the frame needs.
    pub vertex_sun: bool,
    pub ground: bool,
    /// The ground-sun pass drew the ground's sun visibility this frame (render::passes::
    /// ground_sun): the map, the sun's size, the ground's region or the view's need of texels
    /// changed while the map was not moving.
    pub ground_sun: bool,
    /// The vertex-light pass computed the light at the vertices of the meshes that take it from
    /// them (render::passes::model::ModelPass::vertex_light_due): not while the camera only
    /// turns.
    pub vertex_light: bool,
}

/// The vertex-light pass's time in a frame that ran it (`run`): from the end of the pass before
/// it (the vertex-sun pass's split, or the shadow pass; with `pass_timing` each has its own slot)
/// to its own end. Run first, it starts at its own beginning timestamp, which lavapipe writes
/// with its end (docs/PERFORMANCE.md, eleventh session): there the time is missed, and only
/// the frame's wall time holds it.
fn vertex_light_ms(gpu: &Gpu, timer: &GpuTimer, run: PassesRun, pass_timing: bool) -> Result<Option<f64>> {
    if !run.vertex_light {
        return Ok(None);
    }
    let (ticks, period_ns) = timer.read_ticks(gpu)?;
    let end = |slot: u32| ticks[2 * slot as usize + 1];
    let start = match (run.vertex_sun, run.shadow_drawn) {
        (true, _) if pass_timing => end(SUN_SPLIT_SLOT),
        (true, _) | (false, true) => end(SHADOW_SLOT),
        (false, false) => ticks[2 * VERTEX_LIGHT_SLOT as usize],
    };
    Ok(Some(crate::gpu::timer::ticks_to_ms(start, end(VERTEX_LIGHT_SLOT), period_ns)))
}

impl Compositor {
    /// Pipelines and targets for `width`×`height` output, antialiased as the adapter wants
    /// ([`Antialiasing::for_adapter`]).
    pub fn new(gpu: &Gpu, width: u32, height: u32) -> Result<Compositor> {
        Self::with_antialiasing(gpu, width, height, Antialiasing::for_adapter(&gpu.adapter.get_info()))
    }

    /// [`Compositor::new`] with the antialiasing given (the study in `previz bench frame`).
    pub fn with_antialiasing(gpu: &Gpu, width: u32, height: u32, aa: Antialiasing) -> Result<Compositor> {
        gpu.check_size("output", width, height)?;
        gpu.checked("the compositor's render targets", || Self::create(gpu, (width, height), aa, 1))
    }

    /// A still's compositor: drawn at [`supersample::factor_for`] × the `width` × `height`
    /// output (up to `wanted`, a still's [`supersample::STILL_FACTOR`]) and box-filtered down to
    /// it when read back ([`Compositor::render`], [`Compositor::render_layers`]). Its k × k
    /// samples antialias the edges too, so a supersampled still draws one sample each
    /// ([`supersample::antialiasing`]); one of a single sample a pixel (an output too large to
    /// supersample) draws [`Antialiasing::STILL`].
    pub fn supersampled(gpu: &Gpu, width: u32, height: u32, wanted: u32) -> Result<Compositor> {
        gpu.check_size("output", width, height)?;
        let k = supersample::factor_for(width, height, wanted, gpu.device.limits().max_texture_dimension_2d);
        gpu.checked("the compositor's render targets", || Self::create(gpu, (width, height), supersample::antialiasing(k), k))
    }

    /// Samples per side of each output pixel ([`Compositor::supersampled`]; 1 for frames).
    pub fn supersample(&self) -> u32 {
        self.supersample
    }

    /// Pipelines and targets for a `width` × `height` output drawn at `supersample` × its size.
    fn create(gpu: &Gpu, (out_width, out_height): (u32, u32), aa: Antialiasing, supersample: u32) -> Result<Compositor> {
        let (width, height) = (out_width * supersample, out_height * supersample);
        let device = &gpu.device;
        let pipelines = Pipelines::shared(gpu, aa.samples())?;
        let frame_buf = build::uniform_buffer::<FrameUniforms>(device, "frame");
        let instance_buf = build::uniform_buffer::<InstanceUniforms>(device, "instance");
        let light_buf = build::uniform_buffer::<LightUniforms>(device, "light");
        let targets = Targets::new(device, (width, height), aa)?;
        let fxaa = targets.aa_input().map(|input| FxaaPass::new(device, &pipelines, input));
        let shadow = ShadowPass::new(device, &pipelines, &frame_buf, &instance_buf);
        shadow.clear_all(device, &gpu.queue);
        let background = BackgroundPass::new(device, &pipelines, (out_width, out_height), supersample);
        let ground_sun = GroundSunPass::new(device, &pipelines, (&frame_buf, &light_buf), shadow.maps());
        let ground = GroundPass::new(
            (device, &gpu.queue),
            &pipelines,
            (&frame_buf, &light_buf),
            shadow.maps(),
            (ground_sun.uniform(), ground_sun.view()),
        );
        let model_pass = ModelPass::new(gpu, &pipelines);
        let vertex_sun = VertexSunPass::new(device, &pipelines, (&frame_buf, &instance_buf, &light_buf), shadow.maps());
        let shadow_held = vec![None; shadow.sizes().len()];
        Ok(Compositor {
            width,
            height,
            supersample,
            frame_buf,
            instance_buf,
            light_buf,
            targets,
            fxaa,
            antialiasing: aa,
            layer_targets: None,
            shadow,
            vertex_sun,
            vertex_sun_held: None,
            vertex_sun_meshes: Vec::new(),
            vertex_sun_run: None,
            split_view: None,
            background,
            ground,
            ground_sun,
            model_pass,
            env: None,
            env_textures: None,
            environment_writes: 0,
            model: None,
            timer: GpuTimer::new(gpu, TIMER_SLOTS),
            counter: PassCounter::new(gpu, 3),
            pipelines,
            detail: Detail::Frame,
            full_shadow: false,
            level: 0,
            shadow_index: 0,
            passes_run: PassesRun::default(),
            pass_timing: false,
            shadow_redrawn: vec![false; shadow_held.len()],
            shadow_held,
            ground_sky_uploaded: None,
            model_sky_uploaded: None,
            ground_sky_updates: 0,
            ground_in_background: false,
            ground_regions: RegionCache::default(),
            reprojection: None,
            reprojected: false,
            shaded_layers: false,
            reprojection_counts: (0, 0),
        })
    }

    /// The output's size (the frame is drawn at [`Compositor::supersample`] × it).
    pub fn size(&self) -> (u32, u32) {
        (self.width / self.supersample, self.height / self.supersample)
    }

    /// How this compositor antialiases the composite.
    pub fn antialiasing(&self) -> Antialiasing {
        self.antialiasing
    }

    /// Upload the environment cube map, scaled by `exposure` (linear light), and its priors.
    /// `heading` (radians, clockwise from North) is the world direction of the map's front (+Z)
    /// face: 0 for maps already aligned with North, a capture's reference heading otherwise.
    /// A map of the face size already held is written into the textures made for it (the map
    /// and its prefiltered levels; nothing allocated, the bind groups stay): the refresh path of
    /// the live camera frame folded into the environment. On an error the current environment
    /// stays (with reprojection, where its shading compositor took the new one and this one
    /// did not, reprojection stops).
    pub fn set_environment(&mut self, gpu: &Gpu, cube: &CubeMap, exposure: f32, heading: f32) -> Result<()> {
        let prepared = environment::prepare_cached(gpu, cube, exposure, heading)?;
        self.set_prepared_environment(gpu, cube, prepared)
    }

    /// [`Compositor::set_environment`] with the CPU work already done ([`environment::prepare`]
    /// of the same `cube`, e.g. on another thread).
    pub fn set_prepared_environment(&mut self, gpu: &Gpu, cube: &CubeMap, prepared: environment::Prepared) -> Result<()> {
        if let Some(shader) = self.shader_mut() {
            shader.set_prepared_environment(gpu, cube, prepared.clone())?;
        }
        let r = self.write_environment(gpu, cube, prepared);
        self.keep_reprojection_if(r.is_ok());
        r
    }

    /// Reprojection's shading compositor took what this one failed to take: it holds another
    /// environment or model than the frames drawn here, so reprojection stops (every frame
    /// shades here).
    fn keep_reprojection_if(&mut self, both_took_it: bool) {
        if !both_took_it {
            self.reprojection = None;
        }
    }

    fn write_environment(&mut self, gpu: &Gpu, cube: &CubeMap, prepared: environment::Prepared) -> Result<()> {
        let environment::Prepared { levels, env } = prepared;
        // The camera sees the new cube map until its equirectangular source is set again.
        self.background.use_cube();
        self.forget_layers();
        if let Some(textures) = self.env_textures.as_ref().filter(|t| t.size() == cube.size) {
            gpu.checked("the environment cube map", || textures.write(gpu, cube, &levels))?;
            self.env = Some(env);
            self.environment_writes += 1;
            return Ok(());
        }
        let (textures, env_view_bg, model_bg) = gpu.checked("the environment cube map", || {
            let textures = EnvironmentTextures::new(gpu, cube.size);
            textures.write(gpu, cube, &levels)?;
            let views = &textures.views;
            let env_view_bg = BackgroundPass::env_view_bind_group(&gpu.device, &self.pipelines, &self.frame_buf, &views.cube);
            let model_bg = (self.shadow.maps().iter())
                .map(|map| {
                    let buffers = (&self.frame_buf, &self.instance_buf, &self.light_buf);
                    self.model_pass.bind_group(&gpu.device, buffers, views, self.background.view(), map)
                })
                .collect();
            Ok((textures, env_view_bg, model_bg))
        })?;
        self.background.set_env_view_bind_group(env_view_bg);
        self.model_pass.set_bind_groups(model_bg);
        self.env_textures = Some(textures);
        self.env = Some(env);
        self.environment_writes += 1;
        Ok(())
    }

    /// Draw the background of the environment (when no image is given) from `map`, the
    /// equirectangular image the environment last set was made from (scene::environment::
    /// load_environment_and_equirect; heading and exposure are the environment's), looked up
    /// directly and not through the cube map: the cube map still lights the model. `None`, and
    /// any later [`Compositor::set_environment`], go back to the cube map. A map beyond the
    /// device's 2D texture size keeps the cube map.
    pub fn set_equirect_background(&mut self, gpu: &Gpu, map: Option<&Equirect>) -> Result<()> {
        self.forget_layers();
        self.background.set_equirect(gpu, &self.pipelines, &self.frame_buf, map)
    }

    /// Whether the background of the environment is looked up in an equirectangular map
    /// ([`Compositor::set_equirect_background`]) rather than in the cube map.
    pub fn background_sees_equirect(&self) -> bool {
        self.background.sees_equirect()
    }

    /// How many environments have been set (made or refreshed in place) on this compositor.
    pub fn environment_writes(&self) -> usize {
        self.environment_writes
    }

    /// The camera image the frames draw over (the output size, `Rgba8UnormSrgb`): what the live
    /// view folds into its environment before a capture exists (capture::frame_fold).
    pub fn background_view(&self) -> &wgpu::TextureView {
        self.background.view()
    }

    /// The environment's hemisphere priors after exposure (None before `set_environment`).
    pub fn priors(&self) -> Option<HemispherePriors> {
        self.env.as_ref().map(|e| e.priors)
    }

    /// Upload a model: one vertex/index buffer and material bind group per mesh. What the model's
    /// content gives (ambient occlusion, level-of-detail chain) comes from the device's
    /// [`ModelCache`], computed on the first upload of that content. On an error (bad mesh, or
    /// the GPU rejecting the upload) the current model stays (with reprojection, where its
    /// shading compositor took the new one and this one did not, reprojection stops).
    pub fn set_model(&mut self, gpu: &Gpu, model: &Model) -> Result<()> {
        if let Some(shader) = self.shader_mut() {
            shader.set_model(gpu, model)?;
        }
        let r = self.upload_model(gpu, model);
        self.keep_reprojection_if(r.is_ok());
        r
    }

    fn upload_model(&mut self, gpu: &Gpu, model: &Model) -> Result<()> {
        let prepared = ModelCache::of(gpu)?.prepare(model)?;
        let uploaded = gpu.checked("the model's buffers and textures", || self.model_pass.upload(gpu, model, prepared))?;
        self.model = Some(uploaded);
        self.forget_layers();
        self.ground_sky_uploaded = None;
        self.model_sky_uploaded = None;
        self.shadow_held.fill(None);
        self.shadow_redrawn.fill(false);
        self.vertex_sun_held = None;
        self.ground_sun.forget();
        Ok(())
    }

    /// Which level of detail to draw: a frame's (the default), a still's, or the model as loaded
    /// (level 0, for the full-detail references that measure what the levels cost in accuracy).
    pub fn set_detail(&mut self, detail: Detail) {
        self.forget_layers();
        if let Some(shader) = self.shader_mut() {
            shader.set_detail(detail);
        }
        self.detail = detail;
    }

    /// Cull back faces where the frame may (true, the default: single-sided glTF materials, and
    /// closed meshes seen from outside) or draw every triangle after a depth pre-pass: for a
    /// closed mesh the same pixels, for the tests and benchmarks that check and measure it.
    pub fn set_culling(&mut self, on: bool) {
        self.forget_layers();
        if let Some(shader) = self.shader_mut() {
            shader.set_culling(on);
        }
        self.model_pass.set_culling(on);
    }

    /// Let the model's meshes whose triangles are at most `px` pixels long on screen take the
    /// sun's visibility from their vertices, looked up once per shadow map drawn
    /// (`passes::model::MAX_SUN_EDGE_PX`, the default, is the limit measured); 0: the map looked
    /// up per pixel everywhere (docs/PERFORMANCE.md, ninth and tenth sessions).
    pub fn set_sun_edge_limit(&mut self, px: f32) {
        self.forget_layers();
        if let Some(shader) = self.shader_mut() {
            shader.set_sun_edge_limit(px);
        }
        self.model_pass.set_sun_edge_limit(px);
    }

    /// Per mesh of the loaded model, as the last frame drew it: its longest edge on screen
    /// (pixels at the model's nearest point; None where not measured) and whether it took the
    /// sun's visibility from its vertices.
    pub fn sun_per_mesh(&self) -> Vec<(Option<f32>, bool)> {
        self.model_pass.sun_per_mesh()
    }

    /// Let the model's meshes that take the sun from their vertices, whose triangles are at most
    /// `px` pixels long on screen and whose normals turn by at most `turn_scale` times
    /// `passes::model::light_turn_limit` across them take their whole sh9-ggx light from their
    /// vertices (`passes::model::MAX_LIGHT_EDGE_PX` and 1, the defaults, are the limits
    /// measured); `px` 0: every pixel shaded (docs/PERFORMANCE.md, sixteenth session).
    pub fn set_light_limits(&mut self, px: f32, turn_scale: f32) {
        self.forget_layers();
        if let Some(shader) = self.shader_mut() {
            shader.set_light_limits(px, turn_scale);
        }
        self.model_pass.set_light_limits(px, turn_scale);
    }

    /// Per mesh of the loaded model, as the last frame drew it: how far its normal turns across
    /// a triangle (degrees) and whether it took its whole light from its vertices.
    pub fn light_per_mesh(&self) -> Vec<(f32, bool)> {
        self.model_pass.light_per_mesh()
    }

    /// Per mesh of the loaded model, the sun's visibility at each of its vertices as the last
    /// frame that looked it up left it (1 where none did): read back for the tests.
    pub fn vertex_sun_values(&self, gpu: &Gpu) -> Result<Vec<Vec<f32>>> {
        let model = self.model.as_ref().ok_or_else(|| anyhow!("no model set"))?;
        model.sun_buffers().map(|b| Ok(bytemuck::cast_slice(&read_whole(gpu, b)?).to_vec())).collect()
    }

    /// Per mesh of the loaded model, how many triangles of the level the vertex sun last split
    /// take the sun from their vertices and how many look it up per pixel (the two lists'
    /// indirect draws): read back for the tests.
    pub fn vertex_sun_split(&self, gpu: &Gpu) -> Result<Vec<(u32, u32)>> {
        let model = self.model.as_ref().ok_or_else(|| anyhow!("no model set"))?;
        model
            .split_draw_buffers()
            .map(|b| {
                let args: Vec<u32> = bytemuck::cast_slice(&read_whole(gpu, b)?).to_vec();
                Ok((args[0] / 3, args[5] / 3))
            })
            .collect()
    }

    /// Time each pass of the following frames alone ([`Timings::passes`]): the composite's
    /// background, model and ground steps become separate render passes, each with its own
    /// timestamps (a profile: on a tile GPU the split costs memory traffic; lavapipe stores and
    /// loads the target between them).
    pub fn set_pass_timing(&mut self, on: bool) {
        self.pass_timing = on;
    }

    /// Cast the ground's rays for a new turn or scale of the model off the frame's thread
    /// (`PreparedModel::ground_sky_without_waiting`), and make the model's sky for a new turn or
    /// sky there too (`PreparedModel::vertices_under_without_waiting`): the live view. Off, a
    /// frame waits for them.
    pub fn set_ground_in_background(&mut self, on: bool) {
        self.ground_in_background = on;
        if let Some(shader) = self.shader_mut() {
            shader.set_ground_in_background(on);
        }
    }

    /// Draw the shadow into the largest map instead of the one its footprint on screen needs,
    /// and look it up over the whole ground quad instead of only where it can fall: for the
    /// full-shadow references that measure what the smaller maps and the split cost in accuracy.
    pub fn set_full_shadow(&mut self, on: bool) {
        self.forget_layers();
        if let Some(shader) = self.shader_mut() {
            shader.set_full_shadow(on);
        }
        self.full_shadow = on;
    }

    /// Reproject the frames that only turn the camera (the live view; render::reprojection):
    /// the model and its ground are shaded into layers, and a later frame with the same
    /// parameters but the camera's orientation composes them with its own camera image through
    /// the turn. Turning it on makes the layers (the frame's size plus a margin) and the
    /// compositor that shades them, once; off, every frame shades. A frame with FXAA, a
    /// supersampled one, one timed pass by pass, one of a layer other than the composite, and
    /// one over the environment seen by the camera (no camera image) always shade. Returns
    /// whether it is on.
    ///
    /// The layers are shaded by a second compositor of the frame's size plus a margin, which
    /// takes the environment, the model and the settings this one is given from then on: it is
    /// an error to turn it on after setting the environment or the model.
    pub fn set_reprojection(&mut self, gpu: &Gpu, on: bool) -> Result<bool> {
        let possible = on && self.fxaa.is_none() && self.supersample == 1;
        if !possible {
            self.reprojection = None;
        } else if self.reprojection.is_none() {
            if self.env.is_some() || self.model.is_some() {
                anyhow::bail!("reprojection must be turned on before the environment and the model are set");
            }
            let frame = (self.width, self.height);
            let (layer, _) = reprojection::layer_view(1.0, frame);
            let samples = self.antialiasing.samples();
            let mut shader = Compositor::create(gpu, layer, self.antialiasing, 1)?;
            shader.ground_in_background = self.ground_in_background;
            shader.detail = self.detail;
            shader.full_shadow = self.full_shadow;
            let pass = Reprojection::new(&gpu.device, &self.pipelines, self.background.view(), (frame, layer), samples);
            self.reprojection = Some(Reprojecting { pass, shader: Box::new(shader) });
        }
        self.reprojection_counts = (0, 0);
        Ok(self.reprojection.is_some())
    }

    /// The compositor that shades the reprojected layers, when on.
    fn shader_mut(&mut self) -> Option<&mut Compositor> {
        self.reprojection.as_mut().map(|r| &mut *r.shader)
    }

    /// Whether the last frame reprojected the layers instead of shading (render::reprojection).
    pub fn reprojected(&self) -> bool {
        self.reprojected
    }

    /// Frames that reprojected and frames that shaded since reprojection was turned on.
    pub fn reprojection_counts(&self) -> (usize, usize) {
        self.reprojection_counts
    }

    /// The layers hold nothing a later frame can reuse (a new environment, model or setting).
    fn forget_layers(&mut self) {
        if let Some(r) = &mut self.reprojection {
            r.pass.held = None;
        }
    }

    /// The loaded model's level-of-detail chain: per level, triangles (None before a model).
    pub fn lod_triangles(&self) -> Option<&[usize]> {
        self.model.as_ref().map(|m| m.lod_triangles())
    }

    /// The level of detail the last rendered frame drew (0: the model as loaded).
    pub fn lod_level(&self) -> usize {
        self.level
    }

    /// Side of the shadow map the last rendered frame drew into (texels).
    pub fn shadow_map_size(&self) -> u32 {
        self.shadow.sizes()[self.shadow_index]
    }

    /// The ground triangles' vertices the last frame drew with the sun's shadow lookup and
    /// without it (render::frame::GroundMesh).
    pub fn ground_vertices(&self) -> (u32, u32) {
        self.ground.counts()
    }

    /// Which optional passes the last rendered frame ran.
    pub fn passes_run(&self) -> PassesRun {
        self.passes_run
    }

    /// How many times the ground's sky visibility under the model has been uploaded (once per
    /// turn or scale of a model whose sky occlusion is drawn; moving it reuses the map; the
    /// model cache computes each once per device: `PreparedModel::ground_sky_computed`); with
    /// reprojection, the uploads of the compositor that shades its layers too.
    pub fn ground_sky_updates(&self) -> usize {
        self.ground_sky_updates + self.reprojection.as_ref().map_or(0, |r| r.shader.ground_sky_updates())
    }

    /// How many times the ground's sun visibility was drawn into its ground-space texture
    /// (render::passes::ground_sun: once per shadow map kept, region and view's need of texels),
    /// and whether the last frame's ground sampled it (false: looked the sun up, or no sun).
    pub fn ground_sun_bakes(&self) -> (usize, bool) {
        (self.ground_sun.bakes, self.ground.is_sun_baked())
    }

    /// How many times the ground's regions were computed: the shadow's outline (once per
    /// shadow map drawn for the ground) and the sky's visible occlusion (once per sky map and
    /// visible threshold, render::passes::ground::RegionCache).
    pub fn ground_regions_computed(&self) -> (usize, usize) {
        (self.ground_regions.outlines_computed, self.ground_regions.sky_regions_computed)
    }

    /// What was computed from the loaded model's content (shared with every compositor on the
    /// device that loads the same model).
    pub fn prepared_model(&self) -> Option<&Arc<PreparedModel>> {
        self.model.as_ref().map(|m| &m.prepared)
    }

    /// The loaded model's bounds in model space.
    pub fn model_bounds(&self) -> Option<(Vec3, Vec3)> {
        self.model.as_ref().map(|m| m.bounds())
    }

    /// Use a photograph (or a camera frame) as the background, or `None` for the environment
    /// seen by the camera. The image must already be the output size (see
    /// `scene::background::fit`); a camera frame of the same size is re-uploaded with this call
    /// each frame (one `write_texture`).
    pub fn set_background(&mut self, gpu: &Gpu, image: Option<&Rgba8Image>) -> Result<()> {
        self.background.set_image(gpu, image)
    }

    /// Use an image already on the GPU (the camera's YUV converted by `camera::yuv`; the output
    /// size, sRGB-encoded `Rgba8Unorm` bytes) as the background: one GPU copy.
    pub fn set_background_texture(&mut self, gpu: &Gpu, texture: &wgpu::Texture) -> Result<()> {
        self.background.copy_image(gpu, texture)
    }

    /// The uniform values for a frame (pure: no GPU access). A colour correction needs the
    /// model's colour priors (computed on the first frame that asks); a model without any
    /// (every texel masked out) is an error then.
    pub fn frame_uniforms(&self, p: &FrameParams) -> Result<FrameData> {
        Ok(self.frame_data(p, Layer::Composite, &mut RegionCache::default())?.0)
    }

    /// [`Compositor::frame_uniforms`] for a frame of `layer`, with the ground's regions from
    /// (and into) `regions`; also the shadow map this frame keeps (None: it draws the map, or
    /// has none): a frame whose shadow would come out the same as the map's keeps the map and
    /// the sun camera it was drawn with, so lookups match it; and the ground's sky map the
    /// frame draws (None: it draws no sky occlusion), looked up once so that the sky's region
    /// and the uploaded map are the same map even while a new one arrives from the worker.
    fn frame_data(&self, p: &FrameParams, layer: Layer, regions: &mut RegionCache) -> Result<FrameFacts> {
        let env = self.env.as_ref().ok_or_else(|| anyhow!("no environment set"))?;
        let model = self.model.as_ref().ok_or_else(|| anyhow!("no model set"))?;
        let sizes = self.shadow.sizes();
        let context = FrameContext {
            bounds: model.bounds(),
            priors: env.priors,
            exposure: env.exposure,
            env_heading: env.heading,
            size: (self.width, self.height),
            shadow_map_sizes: if self.full_shadow { &sizes[sizes.len() - 1..] } else { sizes },
        };
        let (frame, instance, ground) = frame_uniforms(p, &context);
        let sky = sky_square(model.bounds(), &p.placement);
        let light = light_uniforms(&p.lighting, (sky.min, sky.max));
        let colour = colour_correction(p.colour, &env.colour, || model.prepared.colour())?;
        let min_area = self.detail.min_triangle_area_px();
        let (lod, distance, focal) = lod_level(model.lod_errors(), model.lod_triangles(), model.bounds(), p, self.height, min_area);
        let level = if p.method.bends_rays() { 0 } else { lod };
        // Back faces of a closed mesh are hidden from a camera outside its bounds, those of a
        // single-sided material culled wherever the camera is, unless a mirroring transform
        // turns the faces inside out.
        let cull = match (super::view::model_matrix(model.bounds(), &p.placement).determinant() > 0.0, distance > 0.0) {
            (false, _) => Culling::Nothing,
            (true, false) => Culling::SingleSided,
            (true, true) => Culling::SingleSidedAndClosed,
        };
        let shadow = fit_shadow(p, &context);
        // The model samples the map whatever the sun (its shading uses the visibility beyond the
        // sun's own term), so the shadow pass runs whenever the model or its shadow is on
        // screen; the ground pass only when its shader would darken something (sun up,
        // sunlight and opacity above zero: exactly where its alpha is non-zero).
        let shadow_pass = shadow.footprint.is_some();
        let ground_pass = (shadow.needed && p.lighting.shadow_opacity > 0.0) || (shadow_pass && p.lighting.sky_occlusion > 0.0);
        let mut data = FrameData {
            frame,
            instance,
            ground,
            colour,
            light,
            level,
            px_per_unit: (distance > 0.0).then(|| focal * p.placement.scale.abs() / distance),
            cull,
            shadow_pass,
            ground_pass,
            shadow_map_size: shadow.map_size,
            ground_mesh: GroundMesh::EMPTY,
        };
        let shadow_index = self.shadow.index_of(shadow.map_size);
        let now = ShadowDrawn {
            light_view_proj: glam::Mat4::from_cols_array_2d(&data.frame.light_view_proj),
            model: glam::Mat4::from_cols_array_2d(&data.instance.model),
            level,
        };
        let corners = shadow_fit::box_corners(model.bounds(), now.model);
        let size = self.shadow.sizes()[shadow_index];
        let casting = layer != Layer::Background && shadow_pass;
        let kept = self.shadow_held[shadow_index].filter(|held| casting && shadow_fit::map_still_valid(held, &now, &corners, size));
        if let Some(held) = kept {
            data.frame.light_view_proj = held.light_view_proj.to_cols_array_2d();
        }
        let sky_map =
            if layer == Layer::Composite && ground_pass && p.lighting.sky_occlusion > 0.0 { Some(self.ground_sky(p)?) } else { None };
        if layer == Layer::Composite && ground_pass {
            // Where the ground can darken anything: the shadow's outline in the map the frame
            // looks up, and where the sky's occlusion is visible.
            let outline = match shadow.needed && p.lighting.shadow_opacity > 0.0 && !self.full_shadow {
                true => {
                    let radius = (0.5 * (context.bounds.1 - context.bounds.0).length() * p.placement.scale).max(1e-4);
                    let vertices = || model.prepared.vertices.iter().flatten().map(|v| Vec3::from(v.position));
                    let reach = (size, p.lighting.sun_angular_radius.tan(), radius);
                    let placed = (glam::Mat4::from_cols_array_2d(&data.frame.light_view_proj), now.model);
                    regions.outline(placed, vertices, p.placement.position.z, reach).to_vec()
                }
                false => Vec::new(),
            };
            let sky = match (&sky_map, self.full_shadow) {
                (Some(map), false) => {
                    let per_occlusion = sky_loss_per_occlusion(&data.light, p.lighting.shadow_opacity);
                    // The region is in the map's square, which moves with the model.
                    let [x0, y0, x1, y1] = data.light.ground_square;
                    let (min, max) = (glam::Vec2::new(x0, y0), glam::Vec2::new(x1, y1));
                    let region = regions.sky(map, INVISIBLE_LOSS / per_occlusion.max(1e-12));
                    Some(region.iter().map(|&uv| min + uv * (max - min)).collect::<Vec<_>>())
                }
                _ => None,
            };
            let parts = GroundRegions { outline: &outline, sky: sky.as_deref() };
            data.ground_mesh = ground_mesh(p, &context, &shadow, parts, self.full_shadow);
        }
        Ok((data, kept, sky_map))
    }

    /// Render one image of `layer` and read it back.
    pub fn render(&mut self, gpu: &Gpu, p: &FrameParams, layer: Layer) -> Result<Rendered> {
        let r = gpu.checked("the frame", || self.render_unchecked(gpu, p, layer));
        self.forget_shadows_on_error(r)
    }

    /// After a failed frame no shadow map is known to hold what was noted.
    fn forget_shadows_on_error<T>(&mut self, r: Result<T>) -> Result<T> {
        if r.is_err() {
            self.forget_layers();
            self.shadow_held.fill(None);
            self.shadow_redrawn.fill(false);
            self.vertex_sun_held = None;
            self.ground_sun.forget();
        }
        r
    }

    /// Render one image of `layer` into [`Compositor::target_view`] without reading it back:
    /// the live view samples it in its UI pass. Returns the CPU encode time in ms.
    pub fn draw(&mut self, gpu: &Gpu, p: &FrameParams, layer: Layer) -> Result<f64> {
        let r = gpu.checked("the frame", || {
            let t0 = Instant::now();
            let encoder = self.prepare_frame(gpu, p, layer)?;
            let encode_ms = t0.elapsed().as_secs_f64() * 1e3;
            gpu.queue.submit([encoder.finish()]);
            Ok(encode_ms)
        });
        self.forget_shadows_on_error(r)
    }

    /// The rendered frame (the output size) as an `Rgba8Unorm` view of its sRGB-encoded bytes:
    /// sampling returns the encoded values, which is what egui-wgpu's gamma-space pass wants.
    pub fn target_view(&self) -> &wgpu::TextureView {
        self.targets.encoded_view()
    }

    fn render_unchecked(&mut self, gpu: &Gpu, p: &FrameParams, layer: Layer) -> Result<Rendered> {
        let t0 = Instant::now();
        let mut encoder = self.prepare_frame(gpu, p, layer)?;
        self.targets.copy_for_readback(&mut encoder);
        if let Some(timer) = &self.timer {
            timer.resolve(&mut encoder, TIMER_SLOTS);
        }
        let shader_timer = self
            .reprojection
            .as_ref()
            .filter(|_| self.shaded_layers)
            .and_then(|r| r.shader.timer.as_ref().map(|t| (t, r.shader.passes_run)));
        if let Some((timer, _)) = shader_timer {
            timer.resolve(&mut encoder, TIMER_SLOTS);
        }
        let steps = self.composite_steps(layer);
        let counted: Vec<u32> = (0..3).filter(|&i| steps[i as usize]).collect();
        let counter = self.counter.as_ref().filter(|_| self.pass_timing);
        if let Some(counter) = counter {
            counter.resolve(&mut encoder, &counted);
        }
        let encode_ms = t0.elapsed().as_secs_f64() * 1e3;
        let t1 = Instant::now();
        gpu.queue.submit([encoder.finish()]);
        let k = self.supersample;
        let rgba = match k {
            1 => self.targets.read(gpu)?,
            _ => supersample::box_mean_srgb8(&self.targets.read(gpu)?, (self.width, self.height), k),
        };
        let (gpu_ms, shadow_gpu_ms, passes) = match &self.timer {
            Some(timer) => {
                let ms = timer.read_ms(gpu, TIMER_SLOTS)?;
                let run = self.passes_run;
                let light = vertex_light_ms(gpu, timer, run, self.pass_timing)?.unwrap_or(0.0);
                let mut shadow = (run.shadow_drawn || run.vertex_sun).then_some(ms[SHADOW_SLOT as usize]);
                if self.pass_timing {
                    let steps = self.composite_steps(layer);
                    let ran = |on: bool, slot: u32| on.then_some(ms[slot as usize]);
                    // Each alone: the shadow pass, the vertex sun's lookup and its split. The
                    // lookup's and split's spans end at their passes' ends and start at the end
                    // of the pass before (on lavapipe a compute pass's beginning timestamp is
                    // written with its end; docs/PERFORMANCE.md, eleventh session); a lookup on
                    // a kept map starts at its own beginning timestamp.
                    let vertex_sun = match run.vertex_sun {
                        true => {
                            let (ticks, period_ns) = timer.read_ticks(gpu)?;
                            let end = |slot: u32| ticks[2 * slot as usize + 1];
                            let start = if run.shadow_drawn { end(SHADOW_SLOT) } else { ticks[2 * SUN_LOOKUP_SLOT as usize] };
                            let span = |a: u64, b: u64| crate::gpu::timer::ticks_to_ms(a, b, period_ns);
                            Some([span(start, end(SUN_LOOKUP_SLOT)), span(end(SUN_LOOKUP_SLOT), end(SUN_SPLIT_SLOT))])
                        }
                        false => None,
                    };
                    shadow = (run.shadow_drawn || run.vertex_sun)
                        .then(|| ran(run.shadow_drawn, SHADOW_SLOT).unwrap_or(0.0) + vertex_sun.map_or(0.0, |[a, b]| a + b));
                    let passes = PassTimes {
                        shadow,
                        vertex_sun,
                        background: ran(steps[0], BACKGROUND_SLOT),
                        model: ran(steps[1], MODEL_SLOT).map(|m| m + light),
                        ground: ran(steps[2], GROUND_SLOT).map(|g| g + ran(run.ground_sun, GROUND_SUN_SLOT).unwrap_or(0.0)),
                        fxaa: ran(self.fxaa.is_some(), FXAA_SLOT),
                    };
                    (Some(passes.total()), shadow, Some(passes))
                } else {
                    (Some(ms[REST_SLOT as usize] + shadow.unwrap_or(0.0) + light), shadow, None)
                }
            }
            None => (None, None, None),
        };
        // A frame that shaded the layers: the shading compositor's shadow pass and layer passes.
        let (gpu_ms, shadow_gpu_ms) = match shader_timer {
            Some((timer, run)) => {
                let ms = timer.read_ms(gpu, TIMER_SLOTS)?;
                let shadow = (run.shadow_drawn || run.vertex_sun).then_some(ms[SHADOW_SLOT as usize]);
                let light = vertex_light_ms(gpu, timer, run, false)?.unwrap_or(0.0);
                (gpu_ms.map(|g| g + ms[REST_SLOT as usize] + shadow.unwrap_or(0.0) + light), shadow)
            }
            None => (gpu_ms, shadow_gpu_ms),
        };
        let counts = match counter {
            Some(counter) => {
                let c = counter.read(gpu)?;
                let ran = |step: usize| steps[step].then_some(c[step]);
                Some(PassCounts { background: ran(0), model: ran(1), ground: ran(2) })
            }
            None => None,
        };
        let readback_ms = t1.elapsed().as_secs_f64() * 1e3;
        let timings = Timings { encode_ms, gpu_ms, shadow_gpu_ms, readback_ms, passes, counts, reprojected: self.reprojected };
        Ok(Rendered { width: self.width / k, height: self.height / k, rgba, timings })
    }

    /// Render the frame's layers in float (render/layers.rs: background, shadow matte, model,
    /// depth, and the beauty composed from them) and read them back. The layer targets and
    /// pipelines are made on the first call; the 8-bit frame's are not touched.
    pub fn render_layers(&mut self, gpu: &Gpu, p: &FrameParams) -> Result<LayerImages> {
        let r = gpu.checked("the layers", || {
            // A supersampled still's layers take the frame's samples, so that they compose to
            // its 8-bit image; a frame's layers take 4× MSAA whatever the frame's (their alpha
            // is the coverage).
            let samples = if self.supersample > 1 { self.pipelines.samples } else { LAYER_SAMPLES };
            let pipelines = LayerPipelines::shared(gpu, &self.pipelines, samples)?;
            if self.layer_targets.is_none() {
                self.layer_targets = Some(LayerTargets::new(&gpu.device, (self.width, self.height), samples)?);
            }
            let data = self.write_frame(gpu, p, Layer::Composite)?;
            let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("layers") });
            self.encode_layers(&mut encoder, &pipelines, p.method)?;
            let targets = self.layer_targets.as_ref().ok_or_else(|| anyhow!("no layer targets"))?;
            targets.copy_for_readback(&mut encoder);
            gpu.queue.submit([encoder.finish()]);
            let fine = targets.read(gpu, glam::Mat4::from_cols_array_2d(&data.frame.view_proj), Vec3::from(data.frame.camera_pos))?;
            Ok(supersample::layers_mean(fine, self.supersample))
        });
        self.forget_shadows_on_error(r)
    }

    /// Write the frame's uniforms and encode its passes: with reprojection on, a frame whose
    /// camera only turned composes the held layers; one that shades draws its model and ground
    /// into the layers (the shading compositor, wider than the frame) and composes them, or,
    /// when the layers cannot hold all of both, draws them into the frame.
    fn prepare_frame(&mut self, gpu: &Gpu, p: &FrameParams, layer: Layer) -> Result<wgpu::CommandEncoder> {
        let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("frame") });
        let reprojects = self.reprojection.is_some() && layer == Layer::Composite && !self.pass_timing && !self.background.from_env();
        self.reprojected = reprojects && self.reproject(gpu, p)?;
        self.shaded_layers = false;
        if self.reprojected {
            self.passes_run = PassesRun::default();
            self.reprojection_counts.0 += 1;
            let timestamps = self.timer.as_ref().and_then(|t| t.render_pass(REST_SLOT, true, true));
            self.encode_reprojected(&mut encoder, timestamps)?;
            return Ok(encoder);
        }
        if reprojects {
            self.reprojection_counts.1 += 1;
            let frame = (self.width, self.height);
            let r = self.reprojection.as_mut().ok_or_else(|| anyhow!("reprojection is off"))?;
            r.pass.held = None;
            if r.shader.model.is_some() && r.shader.env.is_some() {
                let (layer_size, vfov) = reprojection::layer_view(p.camera.vfov, frame);
                let wide = FrameParams { camera: super::Camera { vfov, ..p.camera }, ..*p };
                let data = r.shader.write_frame(gpu, &wide, Layer::Composite)?;
                if let Some(mut held) = r.shader.hold(&wide, &data) {
                    held.params = *p;
                    r.pass.held = Some(held);
                    let to_layer = reprojection::homography((p.camera.pose, p.camera.vfov, frame), (p.camera.pose, vfov, layer_size));
                    if r.pass.prepare(&gpu.queue, &to_layer) {
                        r.shader.encode_layers_into(&mut encoder, &r.pass, p.method)?;
                        self.shaded_layers = true;
                        self.passes_run = PassesRun::default();
                        let timestamps = self.timer.as_ref().and_then(|t| t.render_pass(REST_SLOT, true, true));
                        self.encode_reprojected(&mut encoder, timestamps)?;
                        return Ok(encoder);
                    }
                    r.pass.held = None;
                }
            }
        }
        self.write_frame(gpu, p, layer)?;
        self.encode_frame(&mut encoder, layer, p.method)?;
        Ok(encoder)
    }

    /// Whether a frame of `p` can compose the held layers (render::reprojection::reusable, and
    /// the worker's maps the layers drew still the frame's); if so, the homography and the
    /// hull are written for it.
    fn reproject(&mut self, gpu: &Gpu, p: &FrameParams) -> Result<bool> {
        let frame = (self.width, self.height);
        let Some(r) = self.reprojection.as_mut() else { return Ok(false) };
        let Some(held) = r.pass.held.as_ref() else { return Ok(false) };
        if !reprojection::reusable(&held.params, p) {
            return Ok(false);
        }
        let (layer_size, vfov) = reprojection::layer_view(p.camera.vfov, frame);
        let wide = FrameParams { camera: super::Camera { vfov, ..p.camera }, ..*p };
        if let Some(sky) = &held.ground_sky
            && !Arc::ptr_eq(sky, &r.shader.ground_sky(&wide)?)
        {
            return Ok(false);
        }
        if let Some(vertices) = &held.model_sky
            && !Arc::ptr_eq(vertices, &r.shader.model_sky(&wide)?)
        {
            return Ok(false);
        }
        let to_layer = reprojection::homography((p.camera.pose, p.camera.vfov, frame), (held.params.camera.pose, vfov, layer_size));
        Ok(r.pass.prepare(&gpu.queue, &to_layer))
    }

    /// What a shaded frame's layers will hold (None: part of the model or its ground lies
    /// outside the frame, or neither is on screen: the frame draws them into itself).
    fn hold(&self, p: &FrameParams, data: &FrameData) -> Option<Held> {
        let model = self.model.as_ref()?;
        if !data.shadow_pass {
            return None;
        }
        let matrix = glam::Mat4::from_cols_array_2d(&data.instance.model);
        let corners = shadow_fit::box_corners(model.bounds(), matrix);
        let ground = self.passes_run.ground;
        let plane = glam::Mat4::from_cols_array_2d(&data.ground.model);
        let mesh = &data.ground_mesh;
        let drawn = if ground { &mesh.vertices[..(mesh.shadowed + mesh.sky_only) as usize] } else { &[] };
        let triangles: Vec<Vec3> = drawn.iter().map(|&[x, y]| plane.transform_point3(Vec3::new(x, y, 0.0))).collect();
        let view_proj = glam::Mat4::from_cols_array_2d(&data.frame.view_proj);
        let content = reprojection::content_hull(&corners, &triangles, view_proj, (self.width, self.height))?;
        let hull = reprojection::held_part(&content, (self.width, self.height))?;
        let sky_drawn = ground && p.lighting.sky_occlusion > 0.0;
        Some(Held {
            params: *p,
            content,
            hull,
            ground_sky: self.ground_sky_uploaded.clone().filter(|_| sky_drawn),
            model_sky: self.model_sky_uploaded.clone().filter(|_| p.method == super::LightingMethod::Sh9Ggx),
        })
    }

    /// Write the frame's uniforms; note its level of detail and the passes it runs.
    fn write_frame(&mut self, gpu: &Gpu, p: &FrameParams, layer: Layer) -> Result<FrameData> {
        let mut regions = std::mem::take(&mut self.ground_regions);
        let data = self.frame_data(p, layer, &mut regions);
        self.ground_regions = regions;
        let (data, kept, sky_map) = data?;
        let composite = layer == Layer::Composite;
        if let Some(sky) = sky_map {
            self.update_ground_sky(gpu, sky)?;
        }
        let model = self.model.as_ref().ok_or_else(|| anyhow!("no model set"))?;
        let mut vertices_written = false;
        if p.method == super::LightingMethod::Sh9Ggx {
            let vertices = self.model_sky(p)?;
            if !self.model_sky_uploaded.as_ref().is_some_and(|u| Arc::ptr_eq(u, &vertices)) {
                model.write_vertices(&gpu.queue, &vertices);
                self.model_sky_uploaded = Some(vertices);
                vertices_written = true;
            }
        }
        let shadow_index = self.shadow.index_of(data.shadow_map_size);
        let shadow = layer != Layer::Background && data.shadow_pass;
        // Without sunlight (overcast, night) the map is not drawn: every lookup of it is
        // multiplied by the sunlight (model.wgsl, sh9_ggx.wgsl) or skipped (ground.wgsl), so
        // whatever it holds (cleared at creation, or an earlier shadow) changes no pixel.
        let drawn = shadow && kept.is_none() && p.lighting.sunlight > 0.0;
        if drawn {
            self.shadow_held[shadow_index] = Some(ShadowDrawn {
                light_view_proj: glam::Mat4::from_cols_array_2d(&data.frame.light_view_proj),
                model: glam::Mat4::from_cols_array_2d(&data.instance.model),
                level: data.level,
            });
        }
        let queue = &gpu.queue;
        queue.write_buffer(&self.frame_buf, 0, bytemuck::bytes_of(&data.frame));
        queue.write_buffer(&self.instance_buf, 0, bytemuck::bytes_of(&data.instance));
        queue.write_buffer(&self.light_buf, 0, bytemuck::bytes_of(&data.light));
        self.ground.write(queue, &data.ground, &data.ground_mesh);
        if let Some(sky) = &self.ground_sky_uploaded {
            self.ground.write_sky_only(queue, sky, &data.light, data.frame.shadow_opacity);
        }
        // A full-shadow reference looks the sun up per pixel everywhere.
        let sun_px = data.px_per_unit.filter(|_| !self.full_shadow);
        // A still (no frame budget, the accuracy benchmark's) lights every pixel.
        let light = self.detail != Detail::Still;
        let per_vertex = self.model_pass.write(queue, model, (&data.colour, &p.lighting.material), data.cull, (data.level, sun_px, light));
        // A map drawn this frame and by the last frame that sampled it too is moving: the
        // vertex sun's compute would be thrown away a frame later, and costs more than the
        // per-pixel lookup it saves in one frame (docs/PERFORMANCE.md, eleventh session), so
        // such a frame looks the sun up per pixel; the first frame that keeps the map runs it.
        let moving = drawn && self.shadow_redrawn[shadow_index];
        if shadow {
            self.shadow_redrawn[shadow_index] = drawn;
        }
        // The model's sun per vertex: looked up when the map was drawn this frame, or when the
        // buffers hold another map, level, lookup or set of meshes than this frame's (a kept map
        // of another size, a method with another lookup, a mesh now small enough on screen);
        // otherwise they hold what this frame needs. Only for the meshes drawn per vertex.
        let wanted = match (SunLookup::of(p.method), self.shadow_held[shadow_index]) {
            (Some(lookup), Some(map)) if shadow && per_vertex && !moving => {
                Some(VertexSunHeld { shadow_index, map, lookup, tan_sun_radius: data.light.sun[3] })
            }
            _ => None,
        };
        let same_meshes = self.vertex_sun_meshes == self.model_pass.vertex_sun_meshes();
        // The split leaves out the triangles whose backs the camera sees from near where it is:
        // it runs again (with the lookup) when the camera has moved too far or the model moved.
        let view = (glam::Vec3::from(data.frame.camera_pos), glam::Mat4::from_cols_array_2d(&data.instance.model));
        let view_holds =
            self.split_view.is_some_and(|(camera, m)| m == view.1 && vertex_sun::split_holds(camera, m.w_axis.truncate(), view.0));
        self.vertex_sun_run = wanted.filter(|w| drawn || !same_meshes || !view_holds || self.vertex_sun_held != Some(*w)).map(|w| w.lookup);
        if self.vertex_sun_run.is_some() {
            self.split_view = Some(view);
            model.reset_split_draws(queue);
            self.vertex_sun_held = wanted;
            self.vertex_sun_meshes.clear();
            self.vertex_sun_meshes.extend_from_slice(self.model_pass.vertex_sun_meshes());
        } else if drawn {
            // The map changed under buffers that were not looked up again.
            self.vertex_sun_held = None;
        }
        // The meshes draw the sun from their vertices only while the buffers and the split hold
        // this frame's (not for a method without the sun's shadow, nor without a map, nor while
        // the map moves).
        let held = wanted.is_some() && self.vertex_sun_held == wanted && self.vertex_sun_meshes == self.model_pass.vertex_sun_meshes();
        self.model_pass.vertex_sun_valid(held);
        // The light at the vertices (sh9-ggx's light from them): computed again when the sun per
        // vertex, the vertices or what else it reads changed; a camera that only turns reuses it.
        let changed = self.vertex_sun_run.is_some() || vertices_written;
        let uniforms = (&data.frame, &data.instance, &data.light);
        let vertex_light = self.model_pass.vertex_light_due(model, uniforms, data.level, changed);
        // The ground's sun from the ground-sun texture (render::passes::ground_sun) for frames
        // drawn one after another, while the map is not moving (as the vertex sun above); drawn
        // again when the map, the sun's size, the region or the view's need of texels changed.
        // A still and the full-shadow reference look it up per pixel.
        let ground = composite && data.ground_pass && data.shadow_pass;
        let bakes = ground && data.ground_mesh.shadowed > 0 && self.detail == Detail::Frame && !self.full_shadow && !moving;
        let need = bakes.then(|| {
            let plane = glam::Mat4::from_cols_array_2d(&data.ground.model);
            let shadowed = &data.ground_mesh.vertices[..data.ground_mesh.shadowed as usize];
            let region: Vec<glam::Vec2> = shadowed.iter().map(|&[x, y]| plane.transform_point3(Vec3::new(x, y, 0.0)).truncate()).collect();
            let view_proj = glam::Mat4::from_cols_array_2d(&data.frame.view_proj);
            ground_sun::need(&region, plane.w_axis.z, view_proj, (self.width, self.height))
        });
        let baked = match self.shadow_held[shadow_index] {
            Some(map) => self.ground_sun.prepare(queue, need.flatten().as_ref(), (shadow_index, &map, data.light.sun[3])),
            None => {
                self.ground_sun.forget();
                false
            }
        };
        self.ground.sun_baked(baked);
        self.level = data.level;
        self.shadow_index = shadow_index;
        self.passes_run = PassesRun {
            shadow,
            shadow_drawn: drawn,
            vertex_sun: self.vertex_sun_run.is_some(),
            ground,
            ground_sun: self.ground_sun.pending(),
            vertex_light,
        };
        Ok(data)
    }

    /// The sky each of the model's vertices sees under `p`'s sky and turn of the model (sh9-ggx):
    /// the model cache makes it once per turn and sky (the same Arc while they stay); in the
    /// live view on a thread of its own, drawing the previous set meanwhile, as the ground's map.
    fn model_sky(&self, p: &FrameParams) -> Result<super::model_cache::MeshVertices> {
        let model = self.model.as_ref().ok_or_else(|| anyhow!("no model set"))?;
        let env = self.env.as_ref().ok_or_else(|| anyhow!("no environment set"))?;
        let matrix = super::view::model_matrix(model.bounds(), &p.placement);
        let (sky, heading) = (&p.lighting.sky_radiance, env.heading);
        Ok(if self.ground_in_background {
            model.prepared.vertices_under_without_waiting(matrix, sky, heading)
        } else {
            model.prepared.vertices_under(matrix, sky, heading)
        })
    }

    /// The ground's sky visibility under the model as `p` places it and its sky lights it, from
    /// the device's model cache (computed there once per turn or scale of the model and sky
    /// shape; the same `Arc` while they stay).
    fn ground_sky(&self, p: &FrameParams) -> Result<Arc<occlusion::GroundSky>> {
        let model = self.model.as_ref().ok_or_else(|| anyhow!("no model set"))?;
        let env = self.env.as_ref().ok_or_else(|| anyhow!("no environment set"))?;
        let matrix = super::view::model_matrix(model.bounds(), &p.placement);
        // The map moves with the model (its square is centred under it, in the plane of its
        // base), so only a turn or a scale computes it again: dragging the model costs nothing.
        let key = glam::Mat4 { w_axis: glam::Vec4::W, ..matrix };
        // The light the model reflects onto the ground, for its mean albedo.
        let bounce = super::passes::ground::bounce_light(&p.lighting, env.heading, model.prepared.albedo);
        // The rays are weighted by the sky's radiance in bins (light::sh9::SkyRadiance), its
        // nine harmonics being too smooth for a sky concentrated near the horizon or the sun.
        let shape = super::model_cache::GroundLight { radiance: p.lighting.sky_radiance, heading: env.heading, bounce };
        // Computed by the device's model cache once per key (shared by every compositor on the
        // device); in the live view on its worker, drawing the previous map meanwhile.
        Ok(if self.ground_in_background {
            model.prepared.ground_sky_without_waiting(key, shape)
        } else {
            model.prepared.ground_sky(key, shape)
        })
    }

    /// Upload the ground's sky visibility map the frame draws ([`Compositor::ground_sky`]) when
    /// it is not the map already uploaded: after a turn or scale of the model or a new sky shape.
    fn update_ground_sky(&mut self, gpu: &Gpu, sky: Arc<occlusion::GroundSky>) -> Result<()> {
        if self.ground_sky_uploaded.as_ref().is_some_and(|u| Arc::ptr_eq(u, &sky)) {
            return Ok(());
        }
        self.ground.write_sky(&gpu.queue, &sky)?;
        self.ground_sky_uploaded = Some(sky);
        self.ground_sky_updates += 1;
        Ok(())
    }

    /// The passes of one frame, top-down (DESIGN.md "One frame"). The camera image (1.) was
    /// uploaded by `set_background`; nothing here allocates GPU resources. Each pass's commands
    /// are a debug group inside its render pass: groups on the encoder around a pass crash
    /// lavapipe (Mesa 22.3) in `vkCmdBeginDebugUtilsLabelEXT`.
    fn encode_frame(&self, encoder: &mut wgpu::CommandEncoder, layer: Layer, method: super::LightingMethod) -> Result<()> {
        let model = self.model.as_ref().ok_or_else(|| anyhow!("no model set"))?;
        // The first pass after the shadow pass writes the start timestamp, the last pass the end.
        let stamp = |begin: bool, end: bool| self.timer.as_ref().and_then(|t| t.render_pass(REST_SLOT, begin, end));

        // 2-3a. The shadow map and the background texture.
        self.encode_shadow_and_env_view(encoder, model, true)?;

        // 3b-5. Model, background and ground shadow into the composite target: one render pass,
        // or (pass timing) one pass per step, each timed alone. The model is opaque (alpha 1),
        // so the order changes no pixel, only the work: drawn first, its depth keeps the
        // background (at the far plane) and the ground (depth-tested, no depth write) from
        // shading the pixels it covers.
        let first = !self.background.from_env() && !self.passes_run.ground_sun;
        let clear = if layer == Layer::Model { wgpu::Color::TRANSPARENT } else { wgpu::Color::BLACK };
        let steps = self.composite_steps(layer);
        let draw_step = |pass: &mut wgpu::RenderPass<'_>, step: usize| -> Result<()> {
            match step {
                // 3b. Background pass: the camera image fills the target around the model.
                0 => in_group(pass, "background pass", |pass| self.background.draw(pass)),
                // 5. Model pass: shading, reflection/refraction and colour correction. A
                // single-sided material or a closed mesh with its back faces culled; any other
                // after its depth (a pre-pass), so
                // each pixel is shaded once.
                1 => in_group(pass, "model pass", |pass| self.model_pass.draw(pass, model, method, (self.level, self.shadow_index)))?,
                // 4. Ground pass: the shadow catcher darkens the background under the model.
                _ => in_group(pass, "ground pass", |pass| self.ground.draw(pass, self.shadow_index)),
            }
            Ok(())
        };
        let order = [1, 0, 2].into_iter().filter(|&i| steps[i]);
        if self.pass_timing {
            let slots = [BACKGROUND_SLOT, MODEL_SLOT, GROUND_SLOT];
            let run: Vec<usize> = order.collect();
            for (k, &step) in run.iter().enumerate() {
                let last = k + 1 == run.len();
                let timestamps = self.timer.as_ref().and_then(|t| t.render_pass(slots[step], true, true));
                let mut pass = self.targets.begin_composite_part(encoder, (k == 0).then_some(clear), last, timestamps);
                match &self.counter {
                    Some(counter) => counter.count(&mut pass, step as u32, |pass| draw_step(pass, step))?,
                    None => draw_step(&mut pass, step)?,
                }
            }
        } else {
            let mut pass = self.targets.begin_composite(encoder, clear, stamp(first, self.fxaa.is_none()));
            for step in order {
                draw_step(&mut pass, step)?;
            }
        }
        // 5b. Post-process antialiasing into the frame.
        if let Some(fxaa) = &self.fxaa {
            let timestamps = match self.pass_timing {
                true => self.timer.as_ref().and_then(|t| t.render_pass(FXAA_SLOT, true, true)),
                false => stamp(false, true),
            };
            let mut pass = self.targets.begin_fxaa(encoder, timestamps);
            in_group(&mut pass, "fxaa pass", |pass| fxaa.draw(pass));
        }
        Ok(())
    }

    /// The shading compositor's passes for reprojection's layers `r` (render::reprojection): the
    /// shadow pass as a frame's, then the model into the model layer and the ground against the
    /// model's depth into the matte (packed, one sample a pixel: the same layer, in the same
    /// pass). The frame composes them after (`encode_reprojected`).
    fn encode_layers_into(&self, encoder: &mut wgpu::CommandEncoder, r: &Reprojection, method: super::LightingMethod) -> Result<()> {
        let model = self.model.as_ref().ok_or_else(|| anyhow!("no model set"))?;
        let stamp = |begin: bool, end: bool| self.timer.as_ref().and_then(|t| t.render_pass(REST_SLOT, begin, end));
        self.encode_shadow_and_env_view(encoder, model, true)?;
        let first = !self.passes_run.ground_sun;
        let ground = |pass: &mut wgpu::RenderPass<'_>, pipelines: Option<[&wgpu::RenderPipeline; 3]>| {
            if self.passes_run.ground {
                in_group(pass, "ground pass", |pass| match pipelines {
                    Some(p) => self.ground.draw_parts(pass, p, self.shadow_index),
                    None => self.ground.draw(pass, self.shadow_index),
                });
            }
        };
        // Packed: the model, then the ground against its depth with the frame's own pipelines,
        // over the matte 1 with alpha 0.
        let c = f64::from(reprojection::packed_clear());
        let clear = if r.packed() { wgpu::Color { r: c, g: c, b: c, a: 0.0 } } else { wgpu::Color::TRANSPARENT };
        {
            let mut pass = self.targets.begin_into(encoder, (r.model_view(), clear), stamp(first, r.packed()));
            in_group(&mut pass, "model pass", |pass| self.model_pass.draw(pass, model, method, (self.level, self.shadow_index)))?;
            if r.packed() {
                ground(&mut pass, None);
            }
        }
        if let Some(mut pass) = r.begin_matte(encoder, self.targets.depth_view(), stamp(false, true)) {
            ground(&mut pass, r.ground_pipelines());
        }
        Ok(())
    }

    /// The reprojection pass over the held hull, then the background around it, into the
    /// frame: one render pass.
    fn encode_reprojected(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        timestamps: Option<wgpu::RenderPassTimestampWrites<'_>>,
    ) -> Result<()> {
        let r = &self.reprojection.as_ref().ok_or_else(|| anyhow!("reprojection is off"))?.pass;
        let mut pass = self.targets.begin_composite(encoder, wgpu::Color::BLACK, timestamps);
        in_group(&mut pass, "reprojection pass", |pass| r.draw(pass));
        in_group(&mut pass, "background pass", |pass| self.background.draw(pass));
        Ok(())
    }

    /// Which of the composite's steps a frame of `layer` draws: background, model, ground.
    fn composite_steps(&self, layer: Layer) -> [bool; 3] {
        [layer != Layer::Model, layer != Layer::Background, self.passes_run.ground]
    }

    /// Step 2, the shadow pass: the model's depth seen from the sun (not needed for the
    /// background alone); 2b: the sun's visibility at the model's vertices from that map, when
    /// the buffers do not hold it yet; 2c: the sun's visibility on the ground in ground space
    /// (render::passes::ground_sun), when the texture does not hold what the frame needs; step
    /// 3a: the environment seen by the camera becomes the background when there is no image.
    /// `timed`: the shadow pass and 2b are timed together, and 2c or the environment view pass
    /// starts the rest of the frame (with pass timing, 2c is timed with the ground).
    fn encode_shadow_and_env_view(&self, encoder: &mut wgpu::CommandEncoder, model: &ModelGpu, timed: bool) -> Result<()> {
        let shadows = self.passes_run.shadow_drawn;
        let timer = self.timer.as_ref().filter(|_| timed);
        let per_vertex = self.vertex_sun_run;
        if shadows {
            let timestamps = timer.and_then(|t| t.render_pass(SHADOW_SLOT, true, per_vertex.is_none() || self.pass_timing));
            let mut pass = self.shadow.begin(encoder, self.shadow_index, timestamps);
            in_group(&mut pass, "shadow pass", |pass| self.shadow.draw(pass, model, self.level));
        }
        if let Some(lookup) = per_vertex {
            // Timed with the shadow pass (its end written by the split), or (pass timing) the
            // lookup and the split each alone.
            let timestamps = match self.pass_timing {
                true => [
                    timer.and_then(|t| t.compute_pass(SUN_LOOKUP_SLOT, !shadows, true)),
                    timer.and_then(|t| t.compute_pass(SUN_SPLIT_SLOT, false, true)),
                ],
                false => [
                    timer.and_then(|t| t.compute_pass(SHADOW_SLOT, !shadows, false)),
                    timer.and_then(|t| t.compute_pass(SHADOW_SLOT, false, true)),
                ],
            };
            let chosen = self.model_pass.vertex_sun_meshes();
            self.vertex_sun.encode(encoder, (model, chosen), (self.level, self.shadow_index, lookup), timestamps);
        }
        // 2b'. The light at the model's vertices from their sun (sh9-ggx's light from them), when
        // what it depends on changed: timed alone, from the end of the pass before it
        // (`vertex_light_ms`).
        if self.passes_run.vertex_light {
            let timestamps = timer.and_then(|t| t.compute_pass(VERTEX_LIGHT_SLOT, true, true));
            self.model_pass.encode_vertex_light(encoder, model, (self.level, self.shadow_index), timestamps);
        }
        // 2c. The ground's sun visibility from the map, when this frame draws it: timed with the
        // ground (pass timing) or starting the rest of the frame.
        let ground_sun = self.passes_run.ground_sun;
        if ground_sun {
            let slot = if self.pass_timing { GROUND_SUN_SLOT } else { REST_SLOT };
            self.ground_sun.encode(encoder, timer.and_then(|t| t.render_pass(slot, true, self.pass_timing)));
        }
        if self.background.from_env() {
            // With pass timing the environment view is not timed (the background step is).
            let timed = timed && !self.pass_timing;
            let begin = !ground_sun;
            let stamp = |slot: u32, end: bool| if timed { self.timer.as_ref().and_then(|t| t.render_pass(slot, begin, end)) } else { None };
            let mut pass = self.background.begin_env_view(encoder, stamp(REST_SLOT, false));
            in_group(&mut pass, "environment view pass", |pass| self.background.draw_env_view(pass))?;
        }
        Ok(())
    }

    /// The frame's passes for its layers (render/layers.rs), each alone into its float target:
    /// the same shadow map and background texture, then background, ground over white (the
    /// shadow matte), the model over transparent black, and the model's depth.
    fn encode_layers(&self, encoder: &mut wgpu::CommandEncoder, pipelines: &LayerPipelines, method: super::LightingMethod) -> Result<()> {
        let model = self.model.as_ref().ok_or_else(|| anyhow!("no model set"))?;
        let targets = self.layer_targets.as_ref().ok_or_else(|| anyhow!("no layer targets"))?;
        self.encode_shadow_and_env_view(encoder, model, false)?;
        {
            let mut pass = targets.begin(encoder, LayerPass::Background);
            in_group(&mut pass, "background layer", |pass| self.background.draw_with(pass, pipelines.background()));
        }
        {
            let mut pass = targets.begin(encoder, LayerPass::Matte);
            if self.passes_run.ground {
                in_group(&mut pass, "shadow matte layer", |pass| self.ground.draw_with(pass, pipelines.ground(), self.shadow_index));
            }
        }
        {
            let mut pass = targets.begin(encoder, LayerPass::Model);
            in_group(&mut pass, "model layer", |pass| {
                self.model_pass.draw_with(pass, |cull| pipelines.model(method, cull), model, (self.level, self.shadow_index))
            })?;
        }
        let mut pass = targets.begin_depth(encoder);
        in_group(&mut pass, "depth layer", |pass| {
            self.model_pass.draw_with(pass, |cull| pipelines.depth(cull), model, (self.level, self.shadow_index))
        })
    }
}

/// Record `draw` inside a debug group named `name` (what GPU debuggers show for the pass).
fn in_group<T>(pass: &mut wgpu::RenderPass<'_>, name: &str, draw: impl FnOnce(&mut wgpu::RenderPass<'_>) -> T) -> T {
    pass.push_debug_group(name);
    let drawn = draw(pass);
    pass.pop_debug_group();
    drawn
}

/// The bytes of buffer `b` (which has COPY_SRC), through a readback buffer: for the tests'
/// read-backs, not for frames.
fn read_whole(gpu: &Gpu, b: &wgpu::Buffer) -> Result<Vec<u8>> {
    let read = build::buffer(&gpu.device, "readback", b.size(), wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(b, 0, &read, 0, b.size());
    gpu.queue.submit([encoder.finish()]);
    crate::gpu::readback::read_buffer(gpu, &read)
}
