#version 450
// Simple lighting from the normals the runtime computed: a key light, a fill light, ambient.
layout(location = 0) in vec3 v_normal;
layout(location = 1) in vec3 v_color;
layout(location = 0) out vec4 out_color;

void main() {
    vec3 n = normalize(v_normal);
    float key = max(dot(n, normalize(vec3(0.4, 0.8, 0.5))), 0.0);
    float fill = max(dot(n, normalize(vec3(-0.6, 0.3, -0.4))), 0.0);
    vec3 lit = v_color * (0.25 + 0.65 * key + 0.2 * fill);
    out_color = vec4(lit, 1.0);
}
