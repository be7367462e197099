#version 450
// Pass 2: proxy transforms t_c = C1 d_c + C2 q_c for c = x, y, z and every character
// (paper Eq. 5 in the separable form of docs/method.md §8), as ONE matrix product:
//
//     T (4P x 3C) = A (4P x (3P + 4J)) * B ((3P + 4J) x 3C),    A = [C1 | C2],
//
// B column n = 3 ch + c holds [d_c; q_c] of character ch; pass 1 writes it row-major, so the
// invocations of a workgroup (consecutive n) read consecutive B addresses.
//
// Tiling: a workgroup owns 16 rows of T (4 proxies) x 256 columns. Per k-tile it stages the
// 16 x 128 block of A in shared memory (transposed into vec4s of 4 rows), then every invocation
// accumulates four columns, n + 64 i: per k four B loads and 16 vec4 FMAs, each A vec4 used
// four times (A's loads are the same for every invocation, which CPU drivers pay per lane). Rows
// 4b..4b+3 of T are proxy b's row c, so each accumulator is stored as one vec4 of the 3x4 proxy
// transform.
layout(local_size_x = 64) in;

const uint ROWS = 16u;     // rows of T per workgroup (4 proxies)
const uint KT = 128u;      // depth of one staged tile of A
const uint WG = 64u;

layout(std430, set = 0, binding = 0) readonly buffer ProductMatrix { float a[]; };      // 4P x (3P+4J)
layout(std430, set = 0, binding = 1) readonly buffer Rhs { float bmat[]; };      // (3P+4J) x 3 chars
layout(std430, set = 0, binding = 2) buffer Palette { vec4 proxies[]; };   // chars x (P + J) x 3 rows

layout(push_constant) uniform Push { uint P; uint J; uint chars; } pc;

shared vec4 tile_a[KT * 4u];   // tile_a[4k + q] = A rows row0 + 4q .. + 3 at column k0 + k

void main() {
    uint m_rows = 4u * pc.P;
    uint depth = 3u * pc.P + 4u * pc.J;
    uint n_cols = 3u * pc.chars;
    uint lx = gl_LocalInvocationID.x;
    uint n = gl_WorkGroupID.x * 4u * WG + lx;
    uint row0 = gl_WorkGroupID.y * ROWS;

    // acc[4 t + q]: column n + 64 t, rows 4q..4q+3 of the block.
    vec4 acc[16] = vec4[16](vec4(0.0), vec4(0.0), vec4(0.0), vec4(0.0), vec4(0.0), vec4(0.0),
        vec4(0.0), vec4(0.0), vec4(0.0), vec4(0.0), vec4(0.0), vec4(0.0), vec4(0.0), vec4(0.0),
        vec4(0.0), vec4(0.0));
    for (uint k0 = 0u; k0 < depth; k0 += KT) {
        // Stage A: 4 x KT vec4s, each gathering 4 rows of one column.
        for (uint i = lx; i < 4u * KT; i += WG) {
            uint k = i / 4u;
            uint q = i - 4u * k;
            uint col = k0 + k;
            uint r = row0 + 4u * q;
            vec4 v = vec4(0.0);
            if (col < depth) {
                if (r < m_rows) { v.x = a[r * depth + col]; }
                if (r + 1u < m_rows) { v.y = a[(r + 1u) * depth + col]; }
                if (r + 2u < m_rows) { v.z = a[(r + 2u) * depth + col]; }
                if (r + 3u < m_rows) { v.w = a[(r + 3u) * depth + col]; }
            }
            tile_a[i] = v;
        }
        barrier();
        if (n < n_cols) {
            uint kend = min(KT, depth - k0);
            // Columns past the end read a clamped index; their sums are dropped.
            uint m1 = min(n + WG, n_cols - 1u);
            uint m2 = min(n + 2u * WG, n_cols - 1u);
            uint m3 = min(n + 3u * WG, n_cols - 1u);
            for (uint k = 0u; k < kend; k++) {
                uint row = (k0 + k) * n_cols;
                vec4 b = vec4(bmat[row + n], bmat[row + m1], bmat[row + m2], bmat[row + m3]);
                for (uint q = 0u; q < 4u; q++) {
                    vec4 av = tile_a[4u * k + q];
                    acc[q] += av * b.x;
                    acc[4u + q] += av * b.y;
                    acc[8u + q] += av * b.z;
                    acc[12u + q] += av * b.w;
                }
            }
        }
        barrier();
    }
    uint b0 = row0 / 4u;
    for (uint t = 0u; t < 4u; t++) {
        uint col = n + t * WG;
        if (col < n_cols) {
            uint ch = col / 3u;
            uint c = col - 3u * ch;
            for (uint q = 0u; q < 4u; q++) {
                if (b0 + q < pc.P) { proxies[(ch * (pc.P + pc.J) + b0 + q) * 3u + c] = acc[4u * t + q]; }
            }
        }
    }
}
