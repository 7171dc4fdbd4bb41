// Shadow pass: depth of the model seen from the sun (a directional light, orthographic).

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> instance: Instance;

@vertex
fn vs_main(@location(0) position: vec3<f32>) -> @builtin(position) vec4<f32> {
    return frame.light_view_proj * instance.model * vec4<f32>(position, 1.0);
}
