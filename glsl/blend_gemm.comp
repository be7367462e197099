#version 450
// Pass 2: proxy transforms t_c = C1 d_c + C2 q_c for c = x, y, z and every character
// (paper Eq. 5 in the separable form of METHOD.md §8), as ONE matrix product:
//
//     T (4P x 3C) = A (4P x (3P + 4J)) * B ((3P + 4J) x 3C),    A = [C1 | C2],
//     B column n = 3 ch + c holds [d_c; q_c] of character ch.
//
// B is never materialised: rows < 3P read pass 1's gradients, the others read the input bones.
// Tiled: each 16 x 16 workgroup stages a 16 x 16 tile of A and of B in shared memory per step;
// each invocation accumulates TN = 4 outputs along n (one A value reused four times).
layout(local_size_x = 16, local_size_y = 16) in;

const uint TILE = 16u;
const uint TN = 4u;               // columns per invocation: the workgroup covers 16 x 64 of T

layout(std430, set = 0, binding = 0) readonly buffer Matrix { float a[]; };       // 4P x (3P+4J)
layout(std430, set = 0, binding = 1) readonly buffer Gradients { float d[]; };    // chars x P x 9
layout(std430, set = 0, binding = 2) readonly buffer Bones { float bones[]; };    // chars x J x 12
layout(std430, set = 0, binding = 3) buffer Proxies { float proxies[]; };         // chars x P x 12

layout(push_constant) uniform Push { uint P; uint J; uint chars; } pc;

shared float tile_a[TILE * TILE];          // [row][k]
shared float tile_b[TILE * TILE * TN];     // [k][column]

// Element (k, n) of B.
float b_at(uint k, uint n) {
    uint ch = n / 3u;
    uint c = n - 3u * ch;
    if (k < 3u * pc.P) {
        uint l = k / 3u;
        return d[(ch * pc.P + l) * 9u + 3u * c + (k - 3u * l)];
    }
    uint kb = k - 3u * pc.P;
    uint b = kb / 4u;
    return bones[(ch * pc.J + b) * 12u + 4u * c + (kb - 4u * b)];
}

void main() {
    uint m_rows = 4u * pc.P;
    uint depth = 3u * pc.P + 4u * pc.J;
    uint n_cols = 3u * pc.chars;
    uint lx = gl_LocalInvocationID.x;
    uint ly = gl_LocalInvocationID.y;
    uint row = gl_WorkGroupID.y * TILE + ly;
    uint col0 = gl_WorkGroupID.x * TILE * TN;

    float acc[TN] = float[TN](0.0, 0.0, 0.0, 0.0);
    for (uint k0 = 0u; k0 < depth; k0 += TILE) {
        uint ka = k0 + lx;
        tile_a[ly * TILE + lx] = (row < m_rows && ka < depth) ? a[row * depth + ka] : 0.0;
        uint kb = k0 + ly;
        for (uint t = 0u; t < TN; t++) {
            uint n = col0 + t * TILE + lx;
            tile_b[ly * TILE * TN + t * TILE + lx] = (kb < depth && n < n_cols) ? b_at(kb, n) : 0.0;
        }
        barrier();
        for (uint k = 0u; k < TILE; k++) {
            float av = tile_a[ly * TILE + k];
            for (uint t = 0u; t < TN; t++) {
                acc[t] += av * tile_b[k * TILE * TN + t * TILE + lx];
            }
        }
        barrier();
    }
    if (row >= m_rows) {
        return;
    }
    uint b = row / 4u;
    uint j = row - 4u * b;
    for (uint t = 0u; t < TN; t++) {
        uint n = col0 + t * TILE + lx;
        if (n < n_cols) {
            uint ch = n / 3u;
            uint c = n - 3u * ch;
            proxies[(ch * pc.P + b) * 12u + 4u * c + j] = acc[t];
        }
    }
}
