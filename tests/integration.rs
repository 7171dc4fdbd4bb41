//! Every integration test that can share a process, as one test binary: one link, one set of
//! render pipelines compiled per process instead of one per test file, and both test threads
//! busy until the last test (CI time; README "Two commands"). A test file that needs a process of its
//! own (winit's one event loop, the JVM, the wgpu allocation counters of a device no other
//! test uses) is its own `[[test]]` in Cargo.toml; `conventions::every_test_file_is_built`
//! checks that no file in tests/ is left out.

mod common;

mod accuracy_reference;
mod app_export;
mod app_session;
mod app_ui;
mod camera;
mod capture_align;
mod capture_cli;
mod capture_hdr;
mod capture_ui;
mod cli_errors;
mod clipped_sun;
mod colour_cli;
mod colour_correction;
mod composite_cli;
mod conventions;
mod env_background;
mod exr_layers;
mod fuzz_corpus;
mod golden;
mod gpu_errors;
mod hdr_capture_light;
mod layers;
mod live;
mod loaders;
mod lod;
mod raster;
mod reprojection;
mod self_shadow;
mod sun_cli;
mod sun_heading;
mod sun_reference;
mod vertex_light;
mod vertex_sun;
mod yuv;
