// The bone transforms' layout, shared by predict.comp and fused_product.comp (build.rs splices
// `#include` lines: naga has none).

struct Affine { vec4 r0; vec4 r1; vec4 r2; };   // 3x4 row-major bone transform
