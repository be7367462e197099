// Vertex a's blended palette matrix for character ch, sum over its K influences of weight x
// entry (3 rows of a 3x4), shared by skinning and tangents. The includer declares Affine,
// SkinIndex, SkinWeight, Palette, Bones and the push words P and J. The palette is
// [t (P proxies); q (J bones)]: for a reduced model (P > 0) the Palette buffer holds all of it per
// character (the product passes write t, and the bones are copied beside it), so that an
// influence's load does not branch between two buffers (on a CPU driver both sides ran for every
// influence); a plain LBS model (P = 0) reads the bones in place.
Affine blended(uint a, uint ch) {
    Affine sum = Affine(vec4(0.0), vec4(0.0), vec4(0.0));
    uint palette = pc.P + pc.J;
    for (uint k = 0u; k < uint(K); k++) {
        uint i = skin_index[a * uint(K) + k];
        float w = skin_weight[a * uint(K) + k];
        Affine m;
        if (pc.P > 0u) {
            m = proxies[ch * palette + i];
        } else {
            m = bones[ch * pc.J + i];
        }
        sum.r0 += w * m.r0;
        sum.r1 += w * m.r1;
        sum.r2 += w * m.r2;
    }
    return sum;
}
