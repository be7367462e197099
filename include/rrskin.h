/*
 * rrskin: the C ABI of the rrskin runtime (real-time enveloping with rotational regression).
 * `include/rrskin.h` is generated from `src/ffi/` (this module and its files, one a concern) by
 * cbindgen: do not edit it (`RRSKIN_BLESS=1 cargo test --test c_abi` regenerates it). Its
 * preamble is the conventions below followed by the crate's contract (`src/lib.rs`,
 * "## Contract"); `tests/c_abi.rs` puts them together.
 *
 * ## Conventions of every function
 *
 * - Status: it returns an `rrskin_status` (`int32_t`); `RRSKIN_STATUS_OK` is 0. After a
 *   failure, `rrskin_last_error()` returns the calling thread's message (valid until the
 *   thread's next rrskin call). It never unwinds or aborts: every body runs under
 *   `catch_unwind`, and an internal fault gives `RRSKIN_STATUS_ERROR_PANIC`.
 * - Handles: `{ uint64_t id }` values (0 is never valid). `rrskin_*_create` and
 *   `rrskin_*_load_*` give handles the caller destroys with the matching `rrskin_*_destroy`,
 *   in any order. Using a destroyed handle is the caller's error, but it is caught: slots
 *   carry a generation, so a stale handle gives `RRSKIN_STATUS_ERROR_INVALID_HANDLE` instead
 *   of touching freed memory. Borrowed Vulkan objects (engine devices, command buffers) stay
 *   the engine's.
 * - Pointers: a null one gives `RRSKIN_STATUS_ERROR_NULL_POINTER`; array lengths are passed
 *   explicitly and checked (`RRSKIN_STATUS_ERROR_WRONG_LENGTH`). Every function that takes a
 *   pointer is `unsafe`: what a non-null pointer must be is what the library cannot check,
 *   and its `# Safety` section (copied into the header) says it. Pointers are used only
 *   during the call, never kept.
 * - Threads: any function may be called from any thread, and calls on different objects run
 *   concurrently: a global lock covers only the lookup of a handle. Calls on one object are
 *   serialised by that object's own lock: on a crowd, those that change it
 *   (`rrskin_crowd_set_bones`, `rrskin_crowd_set_character_bones`, `rrskin_crowd_read_bounds`)
 *   exclude every other call on it, while reads (`rrskin_crowd_get_output`,
 *   `rrskin_crowd_read_back`) and recordings share it; on a context, recordings and runs
 *   (`rrskin_crowds_record`, `rrskin_crowds_run`, `rrskin_context_get_timings`) take turns,
 *   since they share its query pool. A model is immutable once loaded. Externally
 *   synchronised, as Vulkan says it: the engine's command buffer in `rrskin_crowds_record`
 *   (no other thread records into it during the call), and the engine's queue while the
 *   runtime submits to it (the contract's first duty). The Vulkan rules are the contract's:
 *   no submitted work reading a crowd may be executing when its bones are set or it is
 *   destroyed.
 * - Device loss: once any call sees `VK_ERROR_DEVICE_LOST`, it and every later call on that
 *   context or on a model or crowd of it returns `RRSKIN_STATUS_ERROR_DEVICE_LOST` at once,
 *   submitting nothing; the `rrskin_*_destroy` calls still work, and a new context can be
 *   created. Out-of-memory results of any Vulkan call are `RRSKIN_STATUS_ERROR_ALLOCATION`. A
 *   failed creation leaves no Vulkan object behind and the context usable.
 *
 * ## Contract
 *
 * This section is the contract of the Rust crate and of the C ABI alike: the C header's
 * preamble is made from it (and from the C conventions atop `src/ffi/mod.rs`) by
 * `tests/c_abi.rs`, and tests check its lists against the code. Where the C names differ they
 * are given beside the Rust ones.
 *
 * Errors. Every fallible call returns `Result` (C: an `rrskin_status`). Bad input — a
 * malformed or corrupted model file, inconsistent model parts, bone arrays of the wrong
 * length, NaN/Inf in per-frame input, indices out of range, work beyond a device limit — is an
 * `Error` naming what is wrong, never a panic. A `Model` that exists is valid: every index
 * the GPU reads is in range.
 *
 * The caller's duties (Vulkan makes them impossible to check cheaply):
 * - With an engine's device (`vk::Context::from_engine`, `rrskin_context_create_from_engine`),
 *   the engine's objects must outlive the context, and the queue must be externally
 *   synchronised as Vulkan requires: the runtime submits to it only while loading a model,
 *   running a batch headless and reading outputs back (`rrskin_model_load_*`,
 *   `rrskin_crowds_run`, `rrskin_crowd_read_back`). With the runtime's own device
 *   (`vk::Context::new`, which can enable surface and swapchain extensions), submit and
 *   present inside `vk::Context::with_queue`.
 * - Frames in flight: a crowd is made for F of them (`vk::CrowdOptions::frames_in_flight`,
 *   1 to 4, default 2) and keeps F slots of its per-frame inputs and host-read outputs (bone
 *   transforms, bounds). Set slot f's bones and record frame slot f (`vk::Batch::record`)
 *   only once the GPU finished the last submission that recorded slot f; the other F − 1
 *   slots may be executing meanwhile (the headless path, `vk::Batch::run`, waits itself).
 * - Drop (destroy) a crowd or a GPU model only after the GPU finished every command buffer it
 *   was recorded into. A model keeps its context's device alive, a crowd its model's buffers:
 *   they may be dropped in any order.
 *
 * What a recording does (`vk::Batch::record`, `rrskin_crowds_record`), for an engine
 * that tracks state. Every buffer is a plain `VkBuffer` (no images, no layouts). Before: no
 * state is required — the first command is a global barrier from compute writes, compute
 * reads, transfer reads and (on a graphics queue) vertex-attribute reads of earlier
 * submissions to this recording's compute reads and writes, so last frame's draws of the
 * outputs may still be in flight on the queue. After: a global barrier makes every compute
 * write visible to compute shader reads, transfer reads, host reads and (on a graphics queue)
 * vertex attribute reads. Readers the end barrier does not cover record their own barrier
 * after the recording, from `COMPUTE_SHADER` / `SHADER_WRITE` (the runtime's last writes) to:
 * - vertex pulling (the outputs read as storage buffers in a vertex shader): `VERTEX_SHADER` /
 *   `SHADER_READ` (`SHADER_STORAGE_READ` with synchronization2);
 * - a ray-tracing BLAS built or refitted from the positions:
 *   `ACCELERATION_STRUCTURE_BUILD_KHR` / `SHADER_READ` (VK_KHR_acceleration_structure reads
 *   build inputs with that access);
 * - another stage or family: as Vulkan says for it (another family: after the acquire).
 *
 * In between, per crowd and frame slot f (pass n of the list above; the
 * bounds are written with the normals, a fused product reads the bones, and the proxy
 * correctives read the bones (and, where they see gravity, the characters' up vectors) and
 * update the palette's proxies in place):
 *
 * | buffer | access | memory |
 * |---|---|---|
 * | bone transforms, slot f | compute read (passes 1, 2, 3, 4, 6) | host-visible, written by setting the bones of slot f |
 * | up vectors, slot f | compute read (pass 3) | host-visible, written by setting the up vectors of slot f (models whose proxy correctives see gravity) |
 * | model buffers | compute read | device-local, written once at upload |
 * | B = [d; q] | compute write (pass 1), then read (pass 2) | device-local, internal |
 * | palette [t; q] | compute write (passes 1, 2, 3), then read (passes 3, 4, 6) | device-local, internal |
 * | positions (this frame's buffer) | compute write (pass 4), then read (pass 5) | device-local, vertex + storage + transfer-src |
 * | previous positions | not touched | the buffer the last recorded frame wrote |
 * | normals | compute write (passes 4, 5), then read (pass 6) | device-local, vertex + storage + transfer-src |
 * | bounds, slot f | compute write (pass 5) | host-visible, cached (read back), storage |
 * | tangents | compute write (passes 4, 6) | device-local, vertex + storage + transfer-src |
 * | corrective weights | compute write (pass 1), then read (pass 4) | device-local, internal (models with correctives) |
 *
 * It binds compute pipelines, descriptor set 0 and push constants (bytes 0..24) at
 * `VK_PIPELINE_BIND_POINT_COMPUTE`, and writes timestamps into the batch's own query pool; it
 * leaves the graphics bind point, render passes and dynamic state alone, and never begins,
 * ends or submits the command buffer. The engine re-binds its own compute state after it.
 *
 * Queue family ownership. Every buffer is created `VK_SHARING_MODE_EXCLUSIVE` and used on
 * the context's queue family only: outputs drawn on that family need nothing more. For an
 * engine that reads outputs on another family, `vk::CrowdOptions::release_to_queue_family`
 * (C: `release_outputs` and `release_queue_family`) ends each recording with the release
 * barriers of the frame's outputs (its positions, the normals, its bounds, the tangents: those
 * the crowd has; whole buffers, compute writes); the engine records the matching acquires on
 * its queue after a semaphore wait. The runtime never reads an output a previous recording
 * wrote, so nothing needs to come back: the next recording overwrites it (undefined old
 * contents are never read). The drawn outputs (positions, normals, tangents) are one buffer
 * each, shared by every frame slot (positions alternate between two with previous positions),
 * and the recording's first barrier orders only work on the context's queue: an engine that
 * reads them on another family (async compute) makes the compute submission of the next
 * recording, whatever its slot, wait on a semaphore its reading submission signals after its
 * last read (draws, copies, a BLAS build), or that recording overwrites what is still drawn.
 *
 * Memory and requirements before creation. `vk::model_bytes` and `vk::crowd_bytes`
 * (`rrskin_query_memory`) give the bytes a model and a crowd of C characters will take, from
 * their sizes alone (`vk::ModelSizes::of` a model, including the stored columns of a
 * block-sparse C1/C2); creating a crowd beyond the largest device-local heap is a
 * `DeviceLimit` error, and one with a buffer past the largest the device makes and binds
 * (`maxMemoryAllocationSize`, and `maxBufferSize` with maintenance4; per character:
 * `vk::crowd_largest_buffer_bytes`) a `BufferTooLarge` error naming the buffer, where
 * Vulkan would be undefined behaviour: make several crowds of fewer characters.
 * `vk::requirements` (`rrskin_get_requirements`) gives the Vulkan version (1.1), extensions
 * (none), features (none), queue flags and the storage buffers per stage that every model in
 * every mode runs with, before any device exists; `vk::Context::from_engine` checks the
 * version and that every Vulkan function the runtime calls is there (`MissingFunction`
 * otherwise, never a call through a NULL pointer). A device with fewer storage buffers per
 * stage runs the models whose passes fit: a crowd whose widest pass binds more is a
 * `DeviceLimit` error naming maxPerStageDescriptorStorageBuffers.
 *
 * Threads. `vk::Context` is `Send + Sync`; recording and running take `&mut` on what they
 * write, so Rust's borrow rules are the threading rules. C: any function from any thread; calls
 * on different objects run concurrently (a global lock covers only the lookup of a handle), and
 * calls on one object are serialised by its own lock (see the conventions).
 *
 * Faults. A failed creation (out of memory in any allocation or creation along a model or
 * a crowd, or a failed submission) returns its error and leaves nothing behind: the context
 * stays usable. `VK_ERROR_DEVICE_LOST` becomes `Error::DeviceLost`, and from then on every
 * submission on the context fails with it at once (`vk::Context::check_lost`); objects can
 * still be dropped.
 *
 * Units and layouts. Bone transforms are 3x4 row-major `f32` (`predict::Affine`), world
 * space, relative to the rest pose (`x ↦ Q x + d` takes a rest point to the posed one). Up
 * vectors are 3 `f32` per character in the frame of its bones, the direction opposite to
 * gravity (its length gravity's strength against the training poses'); a crowd starts with the
 * model's up (`Model::up`). Outputs
 * are tightly packed `f32` xyz (12-byte stride), character after character; previous positions
 * likewise (undefined until a crowd recorded two frames); bounds are two std430 `vec4` per
 * character (min xyz, max xyz; `vk::BOUNDS_STRIDE` = 32 bytes); tangents are 4 `f32` per
 * vertex (xyz unit and orthogonal to the normal, w = ±1 with bitangent = cross(n, t) * w, as
 * glTF's TANGENT; `vk::TANGENT_STRIDE` = 16 bytes), zero where the skinned tangent vanishes.
 */

#ifndef RRSKIN_H
#define RRSKIN_H

#include <stddef.h>
#include <stdint.h>

// Status codes (fixed width: `int32_t`).
enum rrskin_status
#if defined(__cplusplus) || __STDC_VERSION__ >= 202311L
  : int32_t
#endif // defined(__cplusplus) || __STDC_VERSION__ >= 202311L
 {
  RRSKIN_STATUS_OK = 0,
  RRSKIN_STATUS_ERROR_NULL_POINTER = 1,
  RRSKIN_STATUS_ERROR_INVALID_HANDLE = 2,
  RRSKIN_STATUS_ERROR_WRONG_LENGTH = 3,
  RRSKIN_STATUS_ERROR_OUT_OF_RANGE = 4,
  RRSKIN_STATUS_ERROR_NON_FINITE = 5,
  RRSKIN_STATUS_ERROR_BAD_MODEL = 6,
  RRSKIN_STATUS_ERROR_IO = 7,
  RRSKIN_STATUS_ERROR_LOADER = 8,
  RRSKIN_STATUS_ERROR_VULKAN = 9,
  RRSKIN_STATUS_ERROR_NO_DEVICE = 10,
  RRSKIN_STATUS_ERROR_MISSING_LAYER = 11,
  RRSKIN_STATUS_ERROR_ALLOCATION = 12,
  RRSKIN_STATUS_ERROR_DEVICE_LIMIT = 13,
  RRSKIN_STATUS_ERROR_NOT_READY = 14,
  RRSKIN_STATUS_ERROR_MISMATCH = 15,
  RRSKIN_STATUS_ERROR_INVALID_ARGUMENT = 16,
  RRSKIN_STATUS_ERROR_PANIC = 17,
  // An optional output asked for from a crowd created without it.
  RRSKIN_STATUS_ERROR_NOT_ENABLED = 18,
  // A Vulkan function the runtime calls is NULL from the engine's `vkGetInstanceProcAddr`.
  RRSKIN_STATUS_ERROR_MISSING_FUNCTION = 19,
  // The model has no data for what was asked (tangents of a model without rest tangents:
  // trained from a mesh without UVs; the engine computes its own or draws without).
  RRSKIN_STATUS_ERROR_NOT_IN_MODEL = 20,
  // The Vulkan device was lost (`VK_ERROR_DEVICE_LOST`): every call on the context and its
  // models and crowds returns this from then on; destroy them and create a new context.
  RRSKIN_STATUS_ERROR_DEVICE_LOST = 21,
};
#ifndef __cplusplus
#if __STDC_VERSION__ >= 202311L
typedef enum rrskin_status rrskin_status;
#else
typedef int32_t rrskin_status;
#endif // __STDC_VERSION__ >= 202311L
#endif // __cplusplus

// What the runtime needs of a Vulkan implementation (`rrskin_get_requirements`): no device
// feature beyond core Vulkan 1.1 is enabled or used.
typedef struct rrskin_requirements {
  // The lowest VkPhysicalDeviceProperties::apiVersion (VK_MAKE_API_VERSION) it runs on.
  uint32_t api_version;
  // VkQueueFlags the context's queue family must have.
  uint32_t queue_flags;
  // The maxPerStageDescriptorStorageBuffers every model runs with in every mode (Vulkan
  // guarantees only 4); a device with fewer runs the models whose passes fit
  // (`rrskin_crowd_create` fails with RRSKIN_ERROR_DEVICE_LIMIT for the others).
  uint32_t storage_buffers_per_stage;
  uint32_t instance_extension_count;
  // `instance_extension_count` extension names to enable on the instance (NULL when 0);
  // static strings.
  const char *const *instance_extensions;
  uint32_t device_extension_count;
  // `device_extension_count` extension names to enable on the device (NULL when 0).
  const char *const *device_extensions;
} rrskin_requirements;

typedef struct rrskin_model_info {
  uint32_t vertices;
  uint32_t triangles;
  uint32_t bones;
  // P; 0 for a plain linear-blend-skinning model.
  uint32_t proxies;
  // K: 4 or 8.
  uint32_t influences;
  // Stored columns of the model's block-sparse C1|C2 (the sum over proxies of the columns
  // any of a proxy's 4 rows touches), 0 where the runtime keeps it dense: what
  // `rrskin_model_get_info` reports, needed for `rrskin_query_memory`'s model bytes.
  uint32_t blend_columns;
  // Nonzero: the model carries rest tangents, so its crowds can output tangents.
  uint32_t tangents;
  // N, the pose-space corrective targets (0 without correctives; at most 64).
  uint32_t correctives;
  // D, the corrective driver bones (0 without correctives).
  uint32_t corrective_drivers;
  // E, the proxies corrected by proxy correctives (0 without them; at most `proxies`).
  uint32_t proxy_correctives;
  // The drivers of all corrected proxies together (0 without proxy correctives).
  uint32_t proxy_corrective_drivers;
  // C, the proxy correctives' kernel centres per joint (0 without kernels; at most 256).
  uint32_t proxy_corrective_kernels;
  // Nonzero: the proxy correctives have the 9 linear features per driver.
  uint32_t proxy_corrective_linear;
  // Nonzero: they have the 3 gravity features per driver too, and crowds read each
  // character's up vector (`rrskin_crowd_set_ups`; the model's `up` by default).
  uint32_t proxy_corrective_gravity;
  // The model's up (unit, in its bones' frame) where `proxy_corrective_gravity`, else zeros.
  float up[3];
  // Entries of the 1-ring fans the recomputed-normals pass reads (about 3 x triangles +
  // 2 x vertices for a closed mesh): what `rrskin_model_get_info` reports, needed for
  // `rrskin_query_memory`'s model bytes.
  uint32_t normal_fan_entries;
  // The words of the P keys' records, all keys together: what `rrskin_model_get_info`
  // reports, needed for `rrskin_query_memory`'s model bytes.
  uint32_t key_words;
} rrskin_model_info;

// How a crowd is made (`rrskin_crowd_create_with_options`); `rrskin_crowd_create` uses
// 2 frames in flight and no optional output.
typedef struct rrskin_crowd_options {
  // F, 1 to 4: the crowd keeps F slots of its bone transforms and bounds, so that frame slot
  // f is set and recorded while the other F - 1 frames still execute.
  uint32_t frames_in_flight;
  // Nonzero: keep last frame's positions in a second buffer (the two alternate, no copy).
  uint32_t previous_positions;
  // Nonzero: write each character's axis-aligned box every frame.
  uint32_t bounds;
  // Nonzero: write a tangent per vertex every frame (for normal-mapped materials);
  // RRSKIN_STATUS_ERROR_NOT_IN_MODEL for a model without rest tangents
  // (`rrskin_model_info.tangents` says).
  uint32_t tangents;
  // Nonzero: end each recording with a queue family ownership release of the frame's
  // outputs (its positions, the normals, its bounds, the tangents; whole buffers) from the context's family
  // to `release_queue_family` (another family of the device, or VK_QUEUE_FAMILY_EXTERNAL),
  // for the engine to acquire there. Nothing needs to come back.
  uint32_t release_outputs;
  uint32_t release_queue_family;
  // How normals (and tangents) are made: RRSKIN_NORMALS_RECOMPUTED (0, the default) from the
  // skinned positions over each vertex's 1-ring by a pass of their own, or
  // RRSKIN_NORMALS_TRANSFORMED (1) in the skinning pass, the rest normal through the
  // cofactor of the vertex's blended matrix (one pass a frame, as engines skin); any other
  // value is RRSKIN_STATUS_ERROR_OUT_OF_RANGE.
  uint32_t normals;
} rrskin_crowd_options;

// A Vulkan context (headless, or wrapping an engine's device).
typedef struct rrskin_context {
  uint64_t id;
} rrskin_context;

// An engine's Vulkan objects, borrowed by `rrskin_context_create_from_engine` (never destroyed
// by rrskin). Dispatchable handles are passed as pointers.
typedef struct rrskin_engine_device {
  // The engine's `vkGetInstanceProcAddr` (PFN_vkGetInstanceProcAddr).
  const void *get_instance_proc_addr;
  // VkInstance
  void *instance;
  // VkPhysicalDevice
  void *physical_device;
  // VkDevice
  void *device;
  uint32_t queue_family_index;
  // VkQueue (of `queue_family_index`; must support compute)
  void *queue;
} rrskin_engine_device;

// A model uploaded to one context.
typedef struct rrskin_model {
  uint64_t id;
} rrskin_model;

// C characters of one model.
typedef struct rrskin_crowd {
  uint64_t id;
} rrskin_crowd;

// Where the engine finds one frame slot's outputs: character c, vertex a is at
// `offset + c * character_stride + a * vertex_stride` bytes in the positions and normals, as
// 3 floats, and at `offset + c * tangent_character_stride + a * tangent_stride` in the
// tangents, as 4; character c's box at `c * bounds_stride` in `bounds`.
typedef struct rrskin_crowd_output {
  // VkBuffer of positions written by the frame (usage: vertex buffer, storage, transfer
  // source).
  uint64_t positions;
  // VkBuffer of the positions of the frame recorded before it (same layout and usage), or 0
  // without previous positions. Undefined until two frames were recorded.
  uint64_t previous_positions;
  // VkBuffer of normals.
  uint64_t normals;
  // VkBuffer of the frame slot's boxes (storage, host-visible): per character 8 floats, min
  // x, y, z, pad, max x, y, z, pad; 0 without bounds.
  uint64_t bounds;
  // VkBuffer of tangents (usage as the normals'): per vertex 4 floats, xyz unit and
  // orthogonal to the normal, w = +-1 with bitangent = cross(normal, xyz) * w (glTF's
  // TANGENT); 0 without tangents.
  uint64_t tangents;
  uint64_t offset;
  uint64_t vertex_stride;
  uint64_t character_stride;
  uint64_t bounds_stride;
  // 16 bytes.
  uint64_t tangent_stride;
  uint64_t tangent_character_stride;
} rrskin_crowd_output;

// GPU time per pass of the last recorded frame, in milliseconds.
typedef struct rrskin_pass_timings {
  // The key predictors and the pose-space corrective weights.
  double predict_ms;
  // The C1/C2 product t = C1 d + C2 q (dense, block-sparse or fused; the Rust `product_ms`).
  double blend_ms;
  // The proxy correctives, T_e (I + E_e) in the palette (0 where no crowd has them).
  double proxy_correctives_ms;
  double skin_ms;
  double normals_ms;
  // 0 without tangents.
  double tangents_ms;
} rrskin_pass_timings;

// A model loaded for CPU palette evaluation. Immutable: every call may run on one from many
// threads at once.
typedef struct rrskin_palette_model {
  uint64_t id;
} rrskin_palette_model;

// What an engine skins with, borrowed from a palette model (valid until it is destroyed).
// Vertex a's position is `M_a * (x_a, 1)`: the blend of 3x4 row-major palette entries
// `M_a = sum over k < influences of weights[a*K + k] * palette[joints[a*K + k]]`, and the
// corrected rest position
// `x_a = rest_positions[a] + sum over n < correctives of w[n] * corrective_targets[n*V + a]`,
// w the character's corrective weights (`rrskin_palette_compute_corrective_weights`; no sum
// without correctives).
typedef struct rrskin_palette_skin {
  // V.
  uint32_t vertices;
  uint32_t triangles;
  // J: bone transforms in.
  uint32_t bones;
  // P: proxies at the front of the palette (0 for a plain linear-blend-skinning model).
  uint32_t proxies;
  // P + J: palette entries out.
  uint32_t palette_entries;
  // K, 4 or 8.
  uint32_t influences;
  // V x K palette indices (< P a proxy, P + b bone b).
  const uint32_t *joints;
  // V x K weights, >= 0, summing to 1 per vertex.
  const float *weights;
  // V x 3.
  const float *rest_positions;
  // V x 3 unit normals of the rest mesh (area-weighted, welded seams shared): the shader
  // takes each through the cofactor of the vertex's blended 3x3, `n.x (c1 x c2) + n.y (c2 x
  // c0) + n.z (c0 x c1)` for its columns c, normalised (the runtime's transformed normals).
  const float *rest_normals;
  // V x 4 (xyz unit, w = +-1 as glTF's TANGENT), or NULL for a model without rest tangents.
  const float *rest_tangents;
  // T x 3 vertex indices.
  const uint32_t *triangle_indices;
  // N, the pose-space corrective targets (0 without correctives; at most 64).
  uint32_t correctives;
  // N x V x 3 rest-space deltas, target-major (as glTF morph targets), or NULL without
  // correctives.
  const float *corrective_targets;
} rrskin_palette_skin;

// A bone transform relative to the rest pose, 3x4 row-major: `x ↦ Q x + d`.
typedef float Affine[12];

#ifdef __cplusplus
extern "C" {
#endif // __cplusplus

// What the runtime needs of the engine's instance, device and queue, before any exists: fill
// `VkInstanceCreateInfo` / `VkDeviceCreateInfo` from it. `rrskin_context_create_from_engine`
// checks the same (RRSKIN_STATUS_ERROR_NO_DEVICE, _DEVICE_LIMIT or _MISSING_FUNCTION).
//
// # Safety
// `out` is NULL or points to writable memory for one `rrskin_requirements`.
rrskin_status rrskin_get_requirements(struct rrskin_requirements *out);

// The bytes of GPU memory a model of `sizes` and a crowd of `characters` of it made with
// `options` (NULL: those of `rrskin_crowd_create`) will take, before either is created (no
// context needed): the sizes of the buffers they create. Either out pointer may be NULL.
// A crowd beyond the largest device-local heap is refused at creation
// (RRSKIN_STATUS_ERROR_DEVICE_LIMIT).
//
// # Safety
// `sizes` is NULL or points to a readable `rrskin_model_info`; `options` is NULL or points to
// a readable `rrskin_crowd_options`; `model_bytes` and `crowd_bytes` are each NULL or point to
// writable memory for one `uint64_t`.
rrskin_status rrskin_query_memory(const struct rrskin_model_info *sizes,
                                  uint32_t characters,
                                  const struct rrskin_crowd_options *options,
                                  uint64_t *model_bytes,
                                  uint64_t *crowd_bytes);

// The calling thread's message for the last failed call ("" after a success). Valid until the
// next rrskin call on this thread; never NULL.
const char *rrskin_last_error(void);

// Creates a context with its own Vulkan instance and device (the best GPU, else lavapipe).
// `validation` != 0 enables the Khronos validation layer with synchronization validation and
// fails with RRSKIN_ERROR_MISSING_LAYER if it is not installed. Destroy with
// `rrskin_context_destroy`.
//
// # Safety
// `out` is NULL or points to writable memory for one `rrskin_context`.
rrskin_status rrskin_context_create_headless(uint32_t validation, struct rrskin_context *out);

// Creates a context on the engine's instance, device and queue. The engine keeps ownership:
// its objects must outlive the context and every model and crowd made from it. The library
// submits to the queue only in `rrskin_model_load_*`, `rrskin_crowds_run` and
// `rrskin_crowd_read_back`; the engine must not use the queue concurrently with those.
//
// # Safety
// `device` is NULL or points to a readable `rrskin_engine_device` whose handles are valid and
// belong together (the instance's physical device; a device made from it with a queue of
// `queue_family_index`; `get_instance_proc_addr` is `vkGetInstanceProcAddr` for the instance)
// and outlive the context and every model and crowd made from it. `out` is NULL or points to
// writable memory for one `rrskin_context`.
rrskin_status rrskin_context_create_from_engine(const struct rrskin_engine_device *device,
                                                struct rrskin_context *out);

// Destroys a context handle. Its device is released once the last model and crowd made from it
// is destroyed too.
rrskin_status rrskin_context_destroy(struct rrskin_context context);

// The number of validation-layer warnings and errors a headless context created with
// validation has collected (0 otherwise).
//
// # Safety
// `out` is NULL or points to writable memory for one `uint32_t`.
rrskin_status rrskin_context_validation_message_count(struct rrskin_context context, uint32_t *out);

// Bytes of device memory the context holds for its models and crowds: `allocated` in live
// allocations, `reserved` in the memory blocks taken from the driver (what counts against the
// engine's budget). Either pointer may be NULL.
//
// # Safety
// `allocated` and `reserved` are each NULL or point to writable memory for one `uint64_t`.
rrskin_status rrskin_context_get_device_memory(struct rrskin_context context,
                                               uint64_t *allocated,
                                               uint64_t *reserved);

// Loads and validates a `.rrs` file (UTF-8 path) and uploads it to `context`.
//
// # Safety
// `path` is NULL or a NUL-terminated string readable during the call; `out` is NULL or points
// to writable memory for one `rrskin_model`.
rrskin_status rrskin_model_load_file(struct rrskin_context context,
                                     const char *path,
                                     struct rrskin_model *out);

// Validates a `.rrs` image of `size` bytes and uploads it to `context` (the bytes are copied).
//
// # Safety
// `data` is NULL or points to `size` readable bytes; `out` is NULL or points to writable memory
// for one `rrskin_model`.
rrskin_status rrskin_model_load_memory(struct rrskin_context context,
                                       const uint8_t *data,
                                       size_t size,
                                       struct rrskin_model *out);

// The model's sizes.
//
// # Safety
// `out` is NULL or points to writable memory for one `rrskin_model_info`.
rrskin_status rrskin_model_get_info(struct rrskin_model model, struct rrskin_model_info *out);

// Destroys a model handle; crowds made from it keep working until destroyed themselves.
rrskin_status rrskin_model_destroy(struct rrskin_model model);

// Creates a crowd of `characters` characters of `model` for 2 frames in flight, all in the
// rest pose.
//
// # Safety
// `out` is NULL or points to writable memory for one `rrskin_crowd`.
rrskin_status rrskin_crowd_create(struct rrskin_model model,
                                  uint32_t characters,
                                  struct rrskin_crowd *out);

// Creates a crowd as `rrskin_crowd_create` does, with `options` (frames in flight out of 1..4:
// RRSKIN_STATUS_ERROR_OUT_OF_RANGE).
//
// # Safety
// `options` is NULL or points to a readable `rrskin_crowd_options`; `out` is NULL or points to
// writable memory for one `rrskin_crowd`.
rrskin_status rrskin_crowd_create_with_options(struct rrskin_model model,
                                               uint32_t characters,
                                               const struct rrskin_crowd_options *options,
                                               struct rrskin_crowd *out);

// Sets every character's bone transforms of frame slot `frame` (0 to F - 1): `float_count` =
// characters x bones x 12 floats, each transform 3x4 row-major, world space, relative to the
// rest pose. The frame slot must not be executing; the other F - 1 may be.
//
// # Safety
// `transforms` is NULL or points to `float_count` readable floats (4-byte aligned) that no
// other thread writes during the call.
rrskin_status rrskin_crowd_set_bones(struct rrskin_crowd crowd,
                                     uint32_t frame,
                                     const float *transforms,
                                     size_t float_count);

// Sets one character's bone transforms of frame slot `frame`: `float_count` = bones x 12.
//
// # Safety
// `transforms` is NULL or points to `float_count` readable floats (4-byte aligned) that no
// other thread writes during the call.
rrskin_status rrskin_crowd_set_character_bones(struct rrskin_crowd crowd,
                                               uint32_t frame,
                                               uint32_t character,
                                               const float *transforms,
                                               size_t float_count);

// Sets every character's up vector of frame slot `frame`: `float_count` = characters x 3, each
// in the character's bones' frame, the direction opposite to gravity (its length gravity's
// strength against the training poses'), for characters tilted by their object transform
// rather than their root bone. A crowd starts with the model's up
// (`rrskin_model_info.up`); a model without `proxy_corrective_gravity` reads none.
//
// # Safety
// `ups` is NULL or points to `float_count` readable floats that no other thread writes during
// the call.
rrskin_status rrskin_crowd_set_ups(struct rrskin_crowd crowd,
                                   uint32_t frame,
                                   const float *ups,
                                   size_t float_count);

// Sets one character's up vector of frame slot `frame` (as `rrskin_crowd_set_ups`).
//
// # Safety
// `up` is NULL or points to 3 readable floats.
rrskin_status rrskin_crowd_set_character_up(struct rrskin_crowd crowd,
                                            uint32_t frame,
                                            uint32_t character,
                                            const float *up);

// The output buffers of frame slot `frame` as last recorded (which positions buffer it
// writes alternates with previous positions: ask after recording the frame), to draw from.
//
// # Safety
// `out` is NULL or points to writable memory for one `rrskin_crowd_output`.
rrskin_status rrskin_crowd_get_output(struct rrskin_crowd crowd,
                                      uint32_t frame,
                                      struct rrskin_crowd_output *out);

// Copies the outputs to host memory: `float_count` = characters x vertices x 3 for each of
// `positions` and `normals` (either may be NULL to skip it). Submits and waits: for tools and
// tests, not the per-frame path.
//
// # Safety
// `positions` and `normals` are each NULL or point to `float_count` writable floats (4-byte
// aligned), not overlapping each other.
rrskin_status rrskin_crowd_read_back(struct rrskin_crowd crowd,
                                     float *positions,
                                     float *normals,
                                     size_t float_count);

// Copies the tangents to host memory: `float_count` = characters x vertices x 4. Submits and
// waits: for tools and tests. RRSKIN_STATUS_ERROR_NOT_ENABLED for a crowd created without
// tangents.
//
// # Safety
// `tangents` is NULL or points to `float_count` writable floats (4-byte aligned).
rrskin_status rrskin_crowd_read_back_tangents(struct rrskin_crowd crowd,
                                              float *tangents,
                                              size_t float_count);

// Reads frame slot `frame`'s boxes from host-visible memory, once the frame's submission
// completed: `float_count` = characters x 6 floats (min x, y, z, max x, y, z per character).
// RRSKIN_STATUS_ERROR_NOT_ENABLED for a crowd created without bounds.
//
// # Safety
// `boxes` is NULL or points to `float_count` writable floats (4-byte aligned).
rrskin_status rrskin_crowd_read_bounds(struct rrskin_crowd crowd,
                                       uint32_t frame,
                                       float *boxes,
                                       size_t float_count);

rrskin_status rrskin_crowd_destroy(struct rrskin_crowd crowd);

// Records frame slot `frame` (0 to F - 1 of every crowd) of all passes of `count` crowds into
// the engine's command buffer (VkCommandBuffer, recording, outside a render pass, on the
// context's queue family). The recorded commands end with a barrier making the outputs visible
// to vertex input, transfer, compute and host reads.
//
// # Safety
// `crowds` is NULL or points to `count` readable `rrskin_crowd` handles. `command_buffer` is
// NULL or a VkCommandBuffer of the context's device, in the recording state, that no other
// thread records into during the call; the engine submits it, and keeps the crowds alive and
// the frame slot's bones unchanged until it completed.
rrskin_status rrskin_crowds_record(struct rrskin_context context,
                                   void *command_buffer,
                                   uint32_t frame,
                                   const struct rrskin_crowd *crowds,
                                   uint32_t count);

// Records frame slot `frame` of all passes of `count` crowds, submits them and waits
// (headless path).
//
// # Safety
// `crowds` is NULL or points to `count` readable `rrskin_crowd` handles.
rrskin_status rrskin_crowds_run(struct rrskin_context context,
                                uint32_t frame,
                                const struct rrskin_crowd *crowds,
                                uint32_t count);

// GPU time per pass of the context's frame slot `frame` as last recorded (after
// `rrskin_crowds_record`, only once the command buffer completed; RRSKIN_ERROR_NOT_READY
// otherwise).
//
// # Safety
// `out` is NULL or points to writable memory for one `rrskin_pass_timings`.
rrskin_status rrskin_context_get_timings(struct rrskin_context context,
                                         uint32_t frame,
                                         struct rrskin_pass_timings *out);

// Loads and validates a `.rrs` file (UTF-8 path) for CPU palette evaluation. Destroy with
// `rrskin_palette_model_destroy`.
//
// # Safety
// `path` is NULL or a NUL-terminated string readable during the call; `out` is NULL or points
// to writable memory for one `rrskin_palette_model`.
rrskin_status rrskin_palette_model_load_file(const char *path, struct rrskin_palette_model *out);

// Validates a `.rrs` image of `size` bytes for CPU palette evaluation (the bytes are copied).
//
// # Safety
// `data` is NULL or points to `size` readable bytes; `out` is NULL or points to writable memory
// for one `rrskin_palette_model`.
rrskin_status rrskin_palette_model_load_memory(const uint8_t *data,
                                               size_t size,
                                               struct rrskin_palette_model *out);

// The model's sizes and skin.
//
// # Safety
// `out` is NULL or points to writable memory for one
// `rrskin_palette_skin`.
rrskin_status rrskin_palette_model_get_skin(struct rrskin_palette_model model,
                                            struct rrskin_palette_skin *out);

// N, the pose-space corrective weights of a character (0 for a model without correctives):
// the floats per character `rrskin_palette_compute_corrective_weights` writes.
//
// # Safety
// `out` is NULL or points to writable memory for one
// `uint32_t`.
rrskin_status rrskin_palette_model_get_corrective_count(struct rrskin_palette_model model,
                                                        uint32_t *out);

// The model's up (3 floats, unit, in its bones' frame) where its proxy correctives see gravity,
// so that `rrskin_palette_compute_with_ups` reads up vectors; zeros where they do not.
//
// # Safety
// `out` is NULL or points to 3 writable floats.
rrskin_status rrskin_palette_model_get_up(struct rrskin_palette_model model, float *out);

// The pose-space corrective weights of `characters` characters on the calling thread: `bones`
// as `rrskin_palette_compute`'s (`bone_floats` = characters * J * 12), `out` characters x N
// floats (`out_floats`; N from `rrskin_palette_model_get_corrective_count`), each character's
// N weights of the skin's `corrective_targets`. For a model without correctives N = 0 and
// `out_floats` must be 0 (`out` may then be NULL). Allocates nothing; takes only the handle
// registry's read lock, to find the model.
//
// # Safety
// `bones` is NULL or points to `bone_floats`
// readable floats; `out` is NULL or points to `out_floats` writable floats; the two do not
// overlap.
rrskin_status rrskin_palette_compute_corrective_weights(struct rrskin_palette_model model,
                                                        const float *bones,
                                                        size_t bone_floats,
                                                        float *out,
                                                        size_t out_floats);

// The palette of `characters` characters on the calling thread: `bones` is characters x J
// transforms (`bone_floats` = characters * J * 12 floats, 3x4 row-major, world space, relative
// to the rest pose), `out` characters x (P + J) palette matrices (`out_floats` floats, same
// layout), proxies first (corrected by the model's proxy correctives where it has them:
// nothing more to apply). Allocates nothing (after a thread's first call for a model of that
// size) and takes only the handle registry's read lock, to find the model: call it from an
// engine's worker threads on disjoint characters.
//
// # Safety
// `bones` is NULL or points to `bone_floats`
// readable floats; `out` is NULL or points to `out_floats` writable floats; the two do not
// overlap.
rrskin_status rrskin_palette_compute(struct rrskin_palette_model model,
                                     const float *bones,
                                     size_t bone_floats,
                                     float *out,
                                     size_t out_floats);

// `rrskin_palette_compute` split over `threads` threads it starts and joins (0: one per
// core), for an engine without a job system of its own. Starting threads allocates.
//
// # Safety
// As `rrskin_palette_compute`.
rrskin_status rrskin_palette_compute_parallel(struct rrskin_palette_model model,
                                              const float *bones,
                                              size_t bone_floats,
                                              float *out,
                                              size_t out_floats,
                                              uint32_t threads);

// `rrskin_palette_compute_parallel` with each character's up vector in its bones' frame:
// `ups` characters x 3 floats (`up_floats`), the direction opposite to gravity, its length
// gravity's strength against the training poses' (for a character tilted by its object
// transform rather than its root bone). NULL with `up_floats` = 0: the model's up
// (`rrskin_palette_model_get_up`). Only a model whose proxy correctives see gravity reads them;
// `threads` = 1 runs on the calling thread.
//
// # Safety
// As `rrskin_palette_compute`; `ups` is NULL or points to `up_floats` readable floats.
rrskin_status rrskin_palette_compute_with_ups(struct rrskin_palette_model model,
                                              const float *bones,
                                              size_t bone_floats,
                                              const float *ups,
                                              size_t up_floats,
                                              float *out,
                                              size_t out_floats,
                                              uint32_t threads);

// Destroys a palette model handle; a call running on it on another thread finishes first (it
// holds the model), and the skin that `rrskin_palette_model_get_skin` lent is invalid after.
rrskin_status rrskin_palette_model_destroy(struct rrskin_palette_model model);

#ifdef __cplusplus
}  // extern "C"
#endif  // __cplusplus

#endif  /* RRSKIN_H */
