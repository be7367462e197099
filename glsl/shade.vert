#version 450
// The renderer's vertex stage (src/vk/render.rs): one draw per character, straight from the
// crowd's output buffers (binding 0 positions, binding 1 normals, 12-byte stride), placed by a
// per-draw offset.
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;

layout(push_constant) uniform Push {
    mat4 view_proj;
    vec4 offset;   // xyz: where this character stands
    vec4 color;    // rgb: its tint
} pc;

layout(location = 0) out vec3 v_normal;
layout(location = 1) out vec3 v_color;

void main() {
    gl_Position = pc.view_proj * vec4(position + pc.offset.xyz, 1.0);
    v_normal = normal;
    v_color = pc.color.rgb;
}
