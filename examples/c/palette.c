/*
 * A C engine that skins with its own code, using rrskin's CPU palette only: no Vulkan (this
 * program is linked without the Vulkan loader). It loads a model, computes each character's
 * palette of P + J 3x4 matrices from its J bone transforms (and, for a model with pose-space
 * correctives, its N corrective weights), skins the rest positions (plus the weighted corrective
 * targets) with the model's K joint indices and weights exactly as a vertex shader would, and
 * checks the result
 * against positions computed by the Rust CPU reference evaluator; then it checks the ABI's
 * answers to bad input. Prints "N passed, M failed" and exits non-zero on any failure.
 *
 *   palette MODEL.rrs POSES.bin EXPECTED.bin FRAMES CHARACTERS
 *
 * POSES.bin and EXPECTED.bin as for examples/c/crowd.c (`rrskin reference` writes them).
 *
 * Build, from the repository root after `cargo build --release`:
 *   cc -std=c11 -o palette examples/c/palette.c -I include target/release/librrskin.a \
 *      -lgcc_s -lutil -lrt -lpthread -lm -ldl
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "rrskin.h"

static int passed = 0, failed = 0;

static void check(int ok, const char *what) {
    if (ok) {
        passed++;
    } else {
        failed++;
        fprintf(stderr, "FAILED: %s (last error: %s)\n", what, rrskin_last_error());
    }
}

static float *read_floats(const char *path, size_t count) {
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "cannot open %s\n", path);
        return NULL;
    }
    float *data = malloc(count * sizeof(float));
    size_t got = data ? fread(data, sizeof(float), count, f) : 0;
    fclose(f);
    if (got != count) {
        fprintf(stderr, "%s: expected %zu floats, read %zu\n", path, count, got);
        free(data);
        return NULL;
    }
    return data;
}

/* What a skinning vertex shader does: add the weighted corrective targets (morph targets) to the
   rest position, blend K palette matrices, apply. */
static void skin_vertex(const rrskin_palette_skin *skin, const float *palette,
                        const float *corrective_weights, uint32_t a, float out[3]) {
    float m[12] = {0};
    for (uint32_t k = 0; k < skin->influences; k++) {
        uint32_t i = a * skin->influences + k;
        const float *entry = palette + 12 * (size_t)skin->joints[i];
        for (int e = 0; e < 12; e++) {
            m[e] += skin->weights[i] * entry[e];
        }
    }
    const float *rest = skin->rest_positions + 3 * (size_t)a;
    float x[3] = {rest[0], rest[1], rest[2]};
    for (uint32_t n = 0; n < skin->correctives; n++) {
        const float *delta = skin->corrective_targets + 3 * ((size_t)n * skin->vertices + a);
        for (int i = 0; i < 3; i++) {
            x[i] += corrective_weights[n] * delta[i];
        }
    }
    for (int r = 0; r < 3; r++) {
        out[r] = m[4 * r] * x[0] + m[4 * r + 1] * x[1] + m[4 * r + 2] * x[2] + m[4 * r + 3];
    }
}

int main(int argc, char **argv) {
    if (argc != 6) {
        fprintf(stderr, "usage: %s MODEL.rrs POSES.bin EXPECTED.bin FRAMES CHARACTERS\n", argv[0]);
        return 2;
    }
    size_t frames = strtoul(argv[4], NULL, 10), characters = strtoul(argv[5], NULL, 10);
    rrskin_palette_model model = {0};
    if (rrskin_palette_model_load_file(argv[1], &model) != RRSKIN_STATUS_OK) {
        fprintf(stderr, "load: %s\n", rrskin_last_error());
        return 1;
    }
    rrskin_palette_skin skin;
    if (rrskin_palette_model_get_skin(model, &skin) != RRSKIN_STATUS_OK) {
        fprintf(stderr, "skin: %s\n", rrskin_last_error());
        return 1;
    }
    size_t bone_floats = characters * skin.bones * 12;
    size_t palette_floats = characters * skin.palette_entries * 12;
    float *poses = read_floats(argv[2], frames * bone_floats);
    float *expected = read_floats(argv[3], frames * characters * skin.vertices * 3);
    float *palette = malloc(palette_floats * sizeof(float));
    uint32_t correctives = 0;
    check(rrskin_palette_model_get_corrective_count(model, &correctives) == RRSKIN_STATUS_OK &&
              correctives == skin.correctives,
          "the corrective count is the skin's");
    size_t weight_floats = characters * correctives;
    /* One float more than needed, so that malloc never sees 0. */
    float *weights = malloc((weight_floats + 1) * sizeof(float));
    if (!poses || !expected || !palette || !weights) {
        return 1;
    }
    for (size_t f = 0; f < frames; f++) {
        /* Frame 0 on the calling thread, the others on 2 threads the library starts. */
        rrskin_status s = f == 0 ? rrskin_palette_compute(model, poses + f * bone_floats, bone_floats,
                                                          palette, palette_floats)
                                 : rrskin_palette_compute_parallel(model, poses + f * bone_floats,
                                                                   bone_floats, palette,
                                                                   palette_floats, 2);
        check(s == RRSKIN_STATUS_OK, "palette of a frame");
        check(rrskin_palette_compute_corrective_weights(model, poses + f * bone_floats, bone_floats,
                                                        weights, weight_floats) == RRSKIN_STATUS_OK,
              "corrective weights of a frame");
        float worst = 0;
        for (size_t c = 0; c < characters; c++) {
            const float *entries = palette + c * skin.palette_entries * 12;
            for (uint32_t a = 0; a < skin.vertices; a++) {
                float p[3];
                skin_vertex(&skin, entries, weights + c * correctives, a, p);
                const float *want = expected + ((f * characters + c) * skin.vertices + a) * 3;
                float d = 0, size = 0;
                for (int i = 0; i < 3; i++) {
                    d += (p[i] - want[i]) * (p[i] - want[i]);
                    size += want[i] * want[i];
                }
                float e = sqrtf(d) / fmaxf(1.0f, sqrtf(size));
                worst = e > worst ? e : worst;
            }
        }
        /* f32 round-off against the f64 reference: rrskin_render's PALETTE_TOLERANCE. */
        check(worst <= 2e-6f, "positions skinned from the palette match the reference");
        printf("frame %zu: worst relative position error %.3g\n", f, worst);
    }
    check(rrskin_palette_compute(model, poses, 13, palette, palette_floats) ==
              RRSKIN_STATUS_ERROR_WRONG_LENGTH,
          "a bone count that is not whole matrices is refused");
    rrskin_palette_model never = {0};
    check(rrskin_palette_compute(never, poses, bone_floats, palette, palette_floats) ==
              RRSKIN_STATUS_ERROR_INVALID_HANDLE,
          "a handle never made is refused");
    check(rrskin_palette_compute_corrective_weights(model, poses, bone_floats, weights,
                                                    weight_floats + 1) ==
              RRSKIN_STATUS_ERROR_WRONG_LENGTH,
          "corrective weights of the wrong length are refused");
    rrskin_palette_model missing = {0};
    check(rrskin_palette_model_load_file("/nonexistent/model.rrs", &missing) == RRSKIN_STATUS_ERROR_IO &&
              missing.id == 0,
          "a missing file is an I/O error");
    check(rrskin_palette_model_destroy(model) == RRSKIN_STATUS_OK, "destroy");
    /* A stale handle is a status, not undefined behaviour: destroyed twice, used after. */
    check(rrskin_palette_model_destroy(model) == RRSKIN_STATUS_ERROR_INVALID_HANDLE,
          "a second destroy is refused");
    check(rrskin_palette_compute(model, poses, bone_floats, palette, palette_floats) ==
              RRSKIN_STATUS_ERROR_INVALID_HANDLE,
          "a destroyed model is refused");
    check(rrskin_palette_model_get_skin(model, &skin) == RRSKIN_STATUS_ERROR_INVALID_HANDLE,
          "a destroyed model's skin is refused");
    free(poses);
    free(expected);
    free(palette);
    free(weights);
    printf("%d passed, %d failed\n", passed, failed);
    return failed == 0 ? 0 : 1;
}
