#version 450
// The renderer's vertex stage (rrskin-render's src/renderer.rs): one draw per character, straight
// from the crowd's output buffers (binding 0 positions, binding 1 normals, 12-byte stride),
// placed by a per-draw offset. Built a second time with VERTEX_COLORS for meshes with a
// per-vertex colour (binding 2), e.g. the demo's error maps.
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
#ifdef VERTEX_COLORS
layout(location = 2) in vec3 vertex_color;
#endif

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
#ifdef VERTEX_COLORS
    v_color = vertex_color * pc.color.rgb;
#else
    v_color = pc.color.rgb;
#endif
}
