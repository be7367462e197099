#version 450
// Pass 2: proxy transforms t_c = C1 d_c + C2 q_c for c = x, y, z and every character
// (paper Eq. 5 in the separable form of METHOD.md §8), as ONE matrix product:
//
//     T (4P x 3C) = A (4P x (3P + 4J)) * B ((3P + 4J) x 3C),    A = [C1 | C2],
//
// B column n = 3 ch + c holds [d_c; q_c] of character ch; pass 1 writes it row-major, so the
// invocations of a workgroup (consecutive n) read consecutive B addresses.
//
// Tiling: a workgroup owns 16 rows of T (4 proxies) x 128 columns. Per k-tile it stages the
// 16 x 128 block of A in shared memory (transposed into vec4s of 4 rows), then every invocation
// accumulates two columns, n and n + 64: per k two B loads and 8 vec4 FMAs, each A vec4 used
// twice (A's loads are the same for every invocation, which CPU drivers pay per lane). Rows
// 4b..4b+3 of T are proxy b's row c, so each accumulator is stored as one vec4 of the 3x4 proxy
// transform.
layout(local_size_x = 64) in;

const uint ROWS = 16u;     // rows of T per workgroup (4 proxies)
const uint KT = 128u;      // depth of one staged tile of A
const uint WG = 64u;

layout(std430, set = 0, binding = 0) readonly buffer Matrix { float a[]; };      // 4P x (3P+4J)
layout(std430, set = 0, binding = 1) readonly buffer Rhs { float bmat[]; };      // (3P+4J) x 3 chars
layout(std430, set = 0, binding = 2) buffer Proxies { vec4 proxies[]; };         // chars x P x 3 rows

layout(push_constant) uniform Push { uint P; uint J; uint chars; } pc;

shared vec4 tile_a[KT * 4u];   // tile_a[4k + q] = A rows row0 + 4q .. + 3 at column k0 + k

void main() {
    uint m_rows = 4u * pc.P;
    uint depth = 3u * pc.P + 4u * pc.J;
    uint n_cols = 3u * pc.chars;
    uint lx = gl_LocalInvocationID.x;
    uint n = gl_WorkGroupID.x * 2u * WG + lx;
    uint n2 = n + WG;
    uint row0 = gl_WorkGroupID.y * ROWS;

    vec4 acc0 = vec4(0.0);
    vec4 acc1 = vec4(0.0);
    vec4 acc2 = vec4(0.0);
    vec4 acc3 = vec4(0.0);
    vec4 bcc0 = vec4(0.0);
    vec4 bcc1 = vec4(0.0);
    vec4 bcc2 = vec4(0.0);
    vec4 bcc3 = vec4(0.0);
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
            // The second column reads a clamped index past the end and its sums are dropped.
            uint m2 = min(n2, n_cols - 1u);
            for (uint k = 0u; k < kend; k++) {
                uint row = (k0 + k) * n_cols;
                float b = bmat[row + n];
                float b2 = bmat[row + m2];
                vec4 a0 = tile_a[4u * k];
                vec4 a1 = tile_a[4u * k + 1u];
                vec4 a2 = tile_a[4u * k + 2u];
                vec4 a3 = tile_a[4u * k + 3u];
                acc0 += a0 * b;
                acc1 += a1 * b;
                acc2 += a2 * b;
                acc3 += a3 * b;
                bcc0 += a0 * b2;
                bcc1 += a1 * b2;
                bcc2 += a2 * b2;
                bcc3 += a3 * b2;
            }
        }
        barrier();
    }
    uint b0 = row0 / 4u;
    // acc_q = rows 4(b0 + q) .. + 3 = proxy b0 + q, row c, columns 0..3 (bcc_q: column n2).
    if (n < n_cols) {
        uint ch = n / 3u;
        uint c = n - 3u * ch;
        if (b0 < pc.P) { proxies[(ch * pc.P + b0) * 3u + c] = acc0; }
        if (b0 + 1u < pc.P) { proxies[(ch * pc.P + b0 + 1u) * 3u + c] = acc1; }
        if (b0 + 2u < pc.P) { proxies[(ch * pc.P + b0 + 2u) * 3u + c] = acc2; }
        if (b0 + 3u < pc.P) { proxies[(ch * pc.P + b0 + 3u) * 3u + c] = acc3; }
    }
    if (n2 < n_cols) {
        uint ch = n2 / 3u;
        uint c = n2 - 3u * ch;
        if (b0 < pc.P) { proxies[(ch * pc.P + b0) * 3u + c] = bcc0; }
        if (b0 + 1u < pc.P) { proxies[(ch * pc.P + b0 + 1u) * 3u + c] = bcc1; }
        if (b0 + 2u < pc.P) { proxies[(ch * pc.P + b0 + 2u) * 3u + c] = bcc2; }
        if (b0 + 3u < pc.P) { proxies[(ch * pc.P + b0 + 3u) * 3u + c] = bcc3; }
    }
}
