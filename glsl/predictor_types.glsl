// The data the key predictors read, shared by predict.comp and fused_product.comp (build.rs
// splices `#include` lines: naga has none).

struct Affine { vec4 r0; vec4 r1; vec4 r2; };   // 3x4 row-major bone transform

// Same word layout as a PRED record of the .rrs file (src/model/file.rs).
struct Predictor {
    uint bone; uint second;      // second = 0xFFFFFFFF: none
    float u; float u2;
    float w[9]; float w2[9];     // row-major 3x3 rotations
    float h[63];                 // H: 9 x 7 row-major
};
