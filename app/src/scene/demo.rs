//! The built-in demo scene (assets/demo/, see its README for sources and licences), embedded in
//! the binary so `previz composite` works from any directory.

use super::{CubeMap, Model, Rgba8Image};
use anyhow::{Context, Result};

/// The demo scene description (same keys as any scene file).
pub const SCENE_TOML: &str = include_str!("../../../assets/demo/demo.toml");

const TRUCK_GLB: &[u8] = include_bytes!("../../../assets/demo/truck.glb");
const BACKGROUND_JPG: &[u8] = include_bytes!("../../../assets/demo/background.jpg");
/// Cube faces in wgpu order +X, −X, +Y, −Y, +Z, −Z.
const FACES: [&[u8]; 6] = [
    include_bytes!("../../../assets/demo/posx.jpg"),
    include_bytes!("../../../assets/demo/negx.jpg"),
    include_bytes!("../../../assets/demo/posy.jpg"),
    include_bytes!("../../../assets/demo/negy.jpg"),
    include_bytes!("../../../assets/demo/posz.jpg"),
    include_bytes!("../../../assets/demo/negz.jpg"),
];

/// The demo model (Cesium Milk Truck, glTF binary).
pub fn model() -> Result<Model> {
    super::model::load_glb_bytes(TRUCK_GLB).context("built-in demo model")
}

/// The demo environment (Humus Park2 cube map).
pub fn environment() -> Result<CubeMap> {
    let decode = |bytes: &[u8]| super::decode::decode_bytes(bytes, &[]).map(|d| d.image).context("built-in demo cube face");
    let faces = [decode(FACES[0])?, decode(FACES[1])?, decode(FACES[2])?, decode(FACES[3])?, decode(FACES[4])?, decode(FACES[5])?];
    super::environment::cube_from_faces(faces).context("built-in demo environment")
}

/// The demo background photograph (the cube map's East face at 1024²).
pub fn background() -> Result<Rgba8Image> {
    let img = super::decode::decode_bytes(BACKGROUND_JPG, &[]).context("built-in demo background")?.image.to_rgba8();
    Ok(Rgba8Image { width: img.width(), height: img.height(), pixels: img.into_raw() })
}
