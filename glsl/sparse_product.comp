#version 450
// Pass 2 for a block-sparse [C1 | C2] (the GEMM's alternative, chosen per model when it
// uploads): the proxy transforms T = [C1 | C2] * B of dense_product.comp, multiplying only the
// columns a proxy's 4 rows touch. One invocation per (character, proxy): for each stored
// column k of proxy e, acc[c] += vals[k] * B[k][3 ch + c] for c = x, y, z, where vals[k] holds
// rows 4e .. 4e + 3 at that column; acc[c] is row c of proxy e's 3x4 transform, stored where
// dense_product stores it. The invocations of a workgroup share the proxy (x counts characters),
// so the loop bounds and the column loads are the same for all of them.
layout(local_size_x = 64) in;

layout(std430, set = 0, binding = 0) readonly buffer ProductOffsets { uint offsets[]; };  // P + 1
layout(std430, set = 0, binding = 1) readonly buffer ProductColumns { uint columns[]; };  // stored
layout(std430, set = 0, binding = 2) readonly buffer ProductValues { vec4 vals[]; };      // stored
layout(std430, set = 0, binding = 3) readonly buffer Rhs { float bmat[]; };   // (3P+4J) x 3 chars
layout(std430, set = 0, binding = 4) buffer Palette { vec4 proxies[]; };  // chars x (P + J) x 3 rows

layout(push_constant) uniform Push { uint P; uint J; uint chars; } pc;

void main() {
    uint ch = gl_GlobalInvocationID.x;
    uint e = gl_WorkGroupID.y;
    if (ch >= pc.chars) { return; }
    uint n_cols = 3u * pc.chars;
    vec4 acc0 = vec4(0.0);
    vec4 acc1 = vec4(0.0);
    vec4 acc2 = vec4(0.0);
    uint end = offsets[e + 1u];
    for (uint i = offsets[e]; i < end; i++) {
        uint at = columns[i] * n_cols + 3u * ch;
        vec4 v = vals[i];
        acc0 += v * bmat[at];
        acc1 += v * bmat[at + 1u];
        acc2 += v * bmat[at + 2u];
    }
    uint out_at = (ch * (pc.P + pc.J) + e) * 3u;
    proxies[out_at] = acc0;
    proxies[out_at + 1u] = acc1;
    proxies[out_at + 2u] = acc2;
}
