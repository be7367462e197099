/*
 * A C "engine" using rrskin: it creates its own VkInstance (validation + synchronization
 * validation, its own messenger) and VkDevice, hands them to rrskin, loads a model, animates a
 * crowd of characters for a few frames with 2 frames in flight, each recorded into its OWN
 * command buffer with a copy of the positions into its own host-visible buffer, and checks every
 * frame's positions (and, given TANGENTS.bin, tangents) against values computed by the Rust CPU
 * evaluator; then it checks the ABI's answers to bad input. Prints "N passed, M failed" and
 * exits non-zero on any failure or validation message.
 *
 *   crowd MODEL.rrs POSES.bin EXPECTED.bin FRAMES CHARACTERS [TANGENTS.bin]
 *
 * POSES.bin: FRAMES x CHARACTERS x BONES x 12 floats (3x4 row-major bone transforms).
 * EXPECTED.bin: FRAMES x CHARACTERS x VERTICES x 3 floats (positions).
 * TANGENTS.bin: FRAMES x CHARACTERS x VERTICES x 4 floats (xyz, handedness w), for a model with
 * rest tangents: the crowd is then made with tangents.
 * `rrskin reference MODEL.rrs --frames 3 --characters 64 --out DIR` writes them (DIR/poses.bin,
 * DIR/expected.bin, and DIR/tangents.bin for a model with tangents) for any model, e.g. one of
 * `rrskin synth`.
 *
 * Build and run, from the repository root after `cargo build --release`:
 *   cc -std=c11 -o crowd examples/c/crowd.c -I include -L target/release -lrrskin -lvulkan -lm
 *   LD_LIBRARY_PATH=target/release ./crowd MODEL.rrs DIR/poses.bin DIR/expected.bin 3 64
 * or statically:
 *   cc -std=c11 -o crowd examples/c/crowd.c -I include target/release/librrskin.a \
 *      -lvulkan -lgcc_s -lutil -lrt -lpthread -lm -ldl
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <vulkan/vulkan.h>

#include "rrskin.h"

static int passed = 0, failed = 0;
static unsigned validation_messages = 0;

static void check(int ok, const char *what) {
    if (ok) {
        passed++;
    } else {
        failed++;
        fprintf(stderr, "FAILED: %s (last error: %s)\n", what, rrskin_last_error());
    }
}

/* Aborts the run on an error that makes going on pointless. */
#define REQUIRE(call)                                                                   \
    do {                                                                                \
        rrskin_status s_ = (call);                                                      \
        if (s_ != RRSKIN_STATUS_OK) {                                                   \
            fprintf(stderr, "%s failed with %d: %s\n", #call, (int)s_, rrskin_last_error()); \
            return 1;                                                                   \
        }                                                                               \
    } while (0)

#define VK_REQUIRE(call)                                          \
    do {                                                          \
        VkResult r_ = (call);                                     \
        if (r_ != VK_SUCCESS) {                                   \
            fprintf(stderr, "%s failed with %d\n", #call, (int)r_); \
            return 1;                                             \
        }                                                         \
    } while (0)

static VKAPI_ATTR VkBool32 VKAPI_CALL on_validation(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                    VkDebugUtilsMessageTypeFlagsEXT types,
                                                    const VkDebugUtilsMessengerCallbackDataEXT *data,
                                                    void *user) {
    (void)severity; (void)types; (void)user;
    validation_messages++;
    fprintf(stderr, "validation: %s\n", data->pMessage);
    return VK_FALSE;
}

static float *read_floats(const char *path, size_t count) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    float *data = malloc(count * sizeof(float));
    size_t got = data ? fread(data, sizeof(float), count, f) : 0;
    fclose(f);
    if (got != count) {
        free(data);
        return NULL;
    }
    return data;
}

int main(int argc, char **argv) {
    if (argc != 6 && argc != 7) {
        fprintf(stderr, "usage: %s MODEL.rrs POSES.bin EXPECTED.bin FRAMES CHARACTERS [TANGENTS.bin]\n", argv[0]);
        return 2;
    }
    const char *tangents_path = argc == 7 ? argv[6] : NULL;
    const char *model_path = argv[1];
    const unsigned frames = (unsigned)atoi(argv[4]), characters = (unsigned)atoi(argv[5]);

    /* --- The engine's own Vulkan objects. --- */
    const char *layers[] = {"VK_LAYER_KHRONOS_validation"};
    const char *extensions[] = {VK_EXT_DEBUG_UTILS_EXTENSION_NAME};
    VkValidationFeatureEnableEXT enables[] = {VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT};
    VkValidationFeaturesEXT features = {.sType = VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT,
                                        .enabledValidationFeatureCount = 1,
                                        .pEnabledValidationFeatures = enables};
    VkApplicationInfo app = {.sType = VK_STRUCTURE_TYPE_APPLICATION_INFO, .apiVersion = VK_API_VERSION_1_2};
    VkInstanceCreateInfo instance_info = {.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO,
                                          .pNext = &features,
                                          .pApplicationInfo = &app,
                                          .enabledLayerCount = 1,
                                          .ppEnabledLayerNames = layers,
                                          .enabledExtensionCount = 1,
                                          .ppEnabledExtensionNames = extensions};
    VkInstance instance;
    VK_REQUIRE(vkCreateInstance(&instance_info, NULL, &instance));
    PFN_vkCreateDebugUtilsMessengerEXT create_messenger =
        (PFN_vkCreateDebugUtilsMessengerEXT)vkGetInstanceProcAddr(instance, "vkCreateDebugUtilsMessengerEXT");
    PFN_vkDestroyDebugUtilsMessengerEXT destroy_messenger =
        (PFN_vkDestroyDebugUtilsMessengerEXT)vkGetInstanceProcAddr(instance, "vkDestroyDebugUtilsMessengerEXT");
    VkDebugUtilsMessengerCreateInfoEXT messenger_info = {
        .sType = VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT,
        .messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT,
        .messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT,
        .pfnUserCallback = on_validation};
    VkDebugUtilsMessengerEXT messenger;
    VK_REQUIRE(create_messenger(instance, &messenger_info, NULL, &messenger));

    uint32_t device_count = 1;
    VkPhysicalDevice physical;
    VkResult enumerated = vkEnumeratePhysicalDevices(instance, &device_count, &physical);
    if ((enumerated != VK_SUCCESS && enumerated != VK_INCOMPLETE) || device_count == 0) {
        fprintf(stderr, "no Vulkan device\n");
        return 1;
    }
    uint32_t family_count = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(physical, &family_count, NULL);
    VkQueueFamilyProperties families[16];
    family_count = family_count > 16 ? 16 : family_count;
    vkGetPhysicalDeviceQueueFamilyProperties(physical, &family_count, families);
    uint32_t family = UINT32_MAX;
    for (uint32_t i = 0; i < family_count && family == UINT32_MAX; i++)
        if (families[i].queueFlags & VK_QUEUE_COMPUTE_BIT) family = i;
    if (family == UINT32_MAX) return 1;
    float priority = 1.0f;
    VkDeviceQueueCreateInfo queue_info = {.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO,
                                          .queueFamilyIndex = family,
                                          .queueCount = 1,
                                          .pQueuePriorities = &priority};
    VkDeviceCreateInfo device_info = {.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO,
                                      .queueCreateInfoCount = 1,
                                      .pQueueCreateInfos = &queue_info};
    VkDevice device;
    VK_REQUIRE(vkCreateDevice(physical, &device_info, NULL, &device));
    VkQueue queue;
    vkGetDeviceQueue(device, family, 0, &queue);
    VkCommandPoolCreateInfo pool_info = {.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO,
                                         .flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT,
                                         .queueFamilyIndex = family};
    VkCommandPool pool;
    VK_REQUIRE(vkCreateCommandPool(device, &pool_info, NULL, &pool));
    /* Two frames in flight: a command buffer, a fence and a read-back buffer per frame slot. */
    enum { IN_FLIGHT = 2 };
    VkCommandBufferAllocateInfo cmd_info = {.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO,
                                            .commandPool = pool,
                                            .level = VK_COMMAND_BUFFER_LEVEL_PRIMARY,
                                            .commandBufferCount = IN_FLIGHT};
    VkCommandBuffer cmds[IN_FLIGHT];
    VK_REQUIRE(vkAllocateCommandBuffers(device, &cmd_info, cmds));
    VkFenceCreateInfo fence_info = {.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    VkFence fences[IN_FLIGHT];
    for (int i = 0; i < IN_FLIGHT; i++) VK_REQUIRE(vkCreateFence(device, &fence_info, NULL, &fences[i]));

    /* --- rrskin on the engine's device. --- */
    rrskin_engine_device engine = {.get_instance_proc_addr = (const void *)vkGetInstanceProcAddr,
                                   .instance = instance,
                                   .physical_device = physical,
                                   .device = device,
                                   .queue_family_index = family,
                                   .queue = queue};
    rrskin_context context;
    REQUIRE(rrskin_context_create_from_engine(&engine, &context));
    rrskin_model model;
    REQUIRE(rrskin_model_load_file(context, model_path, &model));
    rrskin_model_info info;
    REQUIRE(rrskin_model_get_info(model, &info));
    if (tangents_path && !info.tangents) {
        fprintf(stderr, "%s has no rest tangents to check %s against\n", model_path, tangents_path);
        return 1;
    }
    rrskin_crowd_options options = {.frames_in_flight = 2, .tangents = tangents_path != NULL};
    rrskin_crowd crowd;
    REQUIRE(rrskin_crowd_create_with_options(model, characters, &options, &crowd));
    rrskin_crowd_output output;
    REQUIRE(rrskin_crowd_get_output(crowd, 0, &output));
    check(output.positions != 0 && output.vertex_stride == 12 && output.character_stride == 12u * info.vertices,
          "output buffers and strides");
    check(!tangents_path || (output.tangents != 0 && output.tangent_stride == 16 &&
                             output.tangent_character_stride == 16u * info.vertices),
          "tangent buffer and strides");

    const size_t bone_floats = (size_t)characters * info.bones * 12;
    const size_t vertex_floats = (size_t)characters * info.vertices * 3;
    const size_t tangent_floats = tangents_path ? (size_t)characters * info.vertices * 4 : 0;
    float *poses = read_floats(argv[2], frames * bone_floats);
    float *expected = read_floats(argv[3], frames * vertex_floats);
    float *expected_tangents = tangents_path ? read_floats(tangents_path, frames * tangent_floats) : NULL;
    if (!poses || !expected || (tangents_path && !expected_tangents)) {
        fprintf(stderr, "cannot read %s, %s or %s (or out of memory)\n", argv[2], argv[3],
                tangents_path ? tangents_path : "-");
        return 1;
    }

    /* The engine's host-visible copies of each frame slot's positions, then its tangents. */
    VkPhysicalDeviceMemoryProperties memory;
    vkGetPhysicalDeviceMemoryProperties(physical, &memory);
    const VkDeviceSize position_bytes = vertex_floats * sizeof(float);
    const VkDeviceSize copy_bytes = position_bytes + tangent_floats * sizeof(float);
    VkBuffer copies[IN_FLIGHT];
    VkDeviceMemory copy_memory[IN_FLIGHT];
    float *copied[IN_FLIGHT];
    for (int i = 0; i < IN_FLIGHT; i++) {
        VkBufferCreateInfo buffer_info = {.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO,
                                          .size = copy_bytes,
                                          .usage = VK_BUFFER_USAGE_TRANSFER_DST_BIT};
        VK_REQUIRE(vkCreateBuffer(device, &buffer_info, NULL, &copies[i]));
        VkMemoryRequirements needs;
        vkGetBufferMemoryRequirements(device, copies[i], &needs);
        const VkMemoryPropertyFlags host = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
        uint32_t type = UINT32_MAX;
        for (uint32_t t = 0; t < memory.memoryTypeCount && type == UINT32_MAX; t++)
            if ((needs.memoryTypeBits & (1u << t)) && (memory.memoryTypes[t].propertyFlags & host) == host) type = t;
        if (type == UINT32_MAX) return 1;
        VkMemoryAllocateInfo alloc = {.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
                                      .allocationSize = needs.size,
                                      .memoryTypeIndex = type};
        VK_REQUIRE(vkAllocateMemory(device, &alloc, NULL, &copy_memory[i]));
        VK_REQUIRE(vkBindBufferMemory(device, copies[i], copy_memory[i], 0));
        VK_REQUIRE(vkMapMemory(device, copy_memory[i], 0, copy_bytes, 0, (void **)&copied[i]));
    }

    /* Frame n uses slot n % 2: wait for the slot's previous frame (n - 2), check it, then set the
       slot's bones and record while frame n - 1 may still execute. */
    for (unsigned frame = 0; frame < frames + IN_FLIGHT; frame++) {
        const unsigned slot = frame % IN_FLIGHT;
        if (frame >= IN_FLIGHT) {
            const unsigned done = frame - IN_FLIGHT;
            VK_REQUIRE(vkWaitForFences(device, 1, &fences[slot], VK_TRUE, UINT64_MAX));
            VK_REQUIRE(vkResetFences(device, 1, &fences[slot]));
            /* Tolerance as in the Rust tests: 2e-4 relative to max(1, |p|). */
            double worst = 0.0;
            const float *want = expected + done * vertex_floats;
            const float *got = copied[slot];
            for (size_t v = 0; v < vertex_floats / 3; v++) {
                double dx = got[3 * v] - want[3 * v], dy = got[3 * v + 1] - want[3 * v + 1],
                       dz = got[3 * v + 2] - want[3 * v + 2];
                double len = sqrt((double)want[3 * v] * want[3 * v] + (double)want[3 * v + 1] * want[3 * v + 1] +
                                  (double)want[3 * v + 2] * want[3 * v + 2]);
                double err = sqrt(dx * dx + dy * dy + dz * dz) / (len > 1.0 ? len : 1.0);
                if (!(err <= worst)) worst = err; /* NaN counts as worst */
            }
            char what[96];
            snprintf(what, sizeof what, "frame %u: positions match the CPU evaluator (worst %.2e)", done, worst);
            check(worst <= 2e-4, what);
            if (tangents_path) {
                /* Unit xyz within 2e-3 as in the Rust tests (the synthetic grid's normals are all
                   well-conditioned); the handedness exactly. */
                double worst_tangent = 0.0;
                int handedness = 1;
                const float *want_t = expected_tangents + done * tangent_floats;
                const float *got_t = copied[slot] + vertex_floats;
                for (size_t v = 0; v < tangent_floats / 4; v++) {
                    double d = 0.0;
                    for (int c = 0; c < 3; c++) d += pow(got_t[4 * v + c] - want_t[4 * v + c], 2);
                    if (!(sqrt(d) <= worst_tangent)) worst_tangent = sqrt(d);
                    handedness &= got_t[4 * v + 3] == want_t[4 * v + 3];
                }
                snprintf(what, sizeof what, "frame %u: tangents match the CPU evaluator (worst %.2e)", done,
                         worst_tangent);
                check(worst_tangent <= 2e-3 && handedness, what);
            }
            rrskin_pass_timings timings;
            check(rrskin_context_get_timings(context, slot, &timings) == RRSKIN_STATUS_OK && timings.skin_ms > 0.0,
                  "pass timings of the frame slot");
        }
        if (frame >= frames) continue;
        REQUIRE(rrskin_crowd_set_bones(crowd, slot, poses + frame * bone_floats, bone_floats));
        VkCommandBuffer cmd = cmds[slot];
        VK_REQUIRE(vkResetCommandBuffer(cmd, 0));
        VkCommandBufferBeginInfo begin = {.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
        VK_REQUIRE(vkBeginCommandBuffer(cmd, &begin));
        REQUIRE(rrskin_crowds_record(context, cmd, slot, &crowd, 1));
        /* rrskin's closing barrier made the outputs visible to transfer reads. */
        REQUIRE(rrskin_crowd_get_output(crowd, slot, &output));
        VkBufferCopy region = {.srcOffset = output.offset, .dstOffset = 0, .size = position_bytes};
        vkCmdCopyBuffer(cmd, (VkBuffer)(uintptr_t)output.positions, copies[slot], 1, &region);
        if (tangents_path) {
            VkBufferCopy tangent_region = {
                .srcOffset = output.offset, .dstOffset = position_bytes, .size = copy_bytes - position_bytes};
            vkCmdCopyBuffer(cmd, (VkBuffer)(uintptr_t)output.tangents, copies[slot], 1, &tangent_region);
        }
        VkMemoryBarrier to_host = {.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                                   .srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
                                   .dstAccessMask = VK_ACCESS_HOST_READ_BIT};
        vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host, 0, NULL,
                             0, NULL);
        VK_REQUIRE(vkEndCommandBuffer(cmd));
        VkSubmitInfo submit = {.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO, .commandBufferCount = 1, .pCommandBuffers = &cmd};
        VK_REQUIRE(vkQueueSubmit(queue, 1, &submit, fences[slot]));
    }
    check(rrskin_crowds_record(context, cmds[0], IN_FLIGHT, &crowd, 1) == RRSKIN_STATUS_ERROR_OUT_OF_RANGE,
          "a frame slot past the frames in flight");
    check(rrskin_crowd_set_bones(crowd, IN_FLIGHT, poses, bone_floats) == RRSKIN_STATUS_ERROR_OUT_OF_RANGE,
          "bones of a frame slot past the frames in flight");
    float *boxes = malloc(6 * characters * sizeof(float));
    check(boxes && rrskin_crowd_read_bounds(crowd, 0, boxes, 6 * characters) == RRSKIN_STATUS_ERROR_NOT_ENABLED,
          "bounds of a crowd created without them");
    check(rrskin_crowd_read_bounds(crowd, 0, boxes, 5) == RRSKIN_STATUS_ERROR_WRONG_LENGTH, "bounds of the wrong length");
    free(boxes);

    /* --- Bad input: every case answers with a status and a message, never a crash. --- */
    check(rrskin_model_get_info(model, NULL) == RRSKIN_STATUS_ERROR_NULL_POINTER, "NULL out pointer");
    rrskin_model null_model = {0};
    check(rrskin_model_get_info(null_model, &info) == RRSKIN_STATUS_ERROR_INVALID_HANDLE, "null handle");
    rrskin_model not_a_model;
    const char text[] = "this is not a model file at all, just text";
    check(rrskin_model_load_memory(context, (const uint8_t *)text, sizeof text, &not_a_model) ==
              RRSKIN_STATUS_ERROR_BAD_MODEL && strstr(rrskin_last_error(), "bad magic"),
          "a model file that is not a model");
    check(rrskin_model_load_file(context, "/nonexistent/model.rrs", &not_a_model) == RRSKIN_STATUS_ERROR_IO &&
              strstr(rrskin_last_error(), "/nonexistent/model.rrs"),
          "a missing model file is named");
    check(rrskin_crowd_set_bones(crowd, 0, poses, bone_floats - 12) == RRSKIN_STATUS_ERROR_WRONG_LENGTH,
          "pose array of the wrong bone count");
    check(rrskin_crowd_set_bones(crowd, 0, poses, bone_floats - 5) == RRSKIN_STATUS_ERROR_WRONG_LENGTH,
          "pose array not made of 3x4 transforms");
    check(rrskin_crowd_set_bones(crowd, 0, NULL, bone_floats) == RRSKIN_STATUS_ERROR_NULL_POINTER, "NULL poses");
    check(rrskin_crowd_set_character_bones(crowd, 0, characters, poses, info.bones * 12) ==
              RRSKIN_STATUS_ERROR_OUT_OF_RANGE,
          "character index past the crowd");
    float *nan_pose = malloc(info.bones * 12 * sizeof(float));
    if (!nan_pose) return 1;
    memcpy(nan_pose, poses, info.bones * 12 * sizeof(float));
    nan_pose[5] = NAN;
    check(rrskin_crowd_set_character_bones(crowd, 0, 0, nan_pose, info.bones * 12) == RRSKIN_STATUS_ERROR_NON_FINITE &&
              strstr(rrskin_last_error(), "not finite"),
          "NaN in a pose");
    free(nan_pose);
    check(rrskin_crowds_record(context, NULL, 0, &crowd, 1) == RRSKIN_STATUS_ERROR_NULL_POINTER, "NULL command buffer");
    rrskin_crowd doomed;
    REQUIRE(rrskin_crowd_create(model, 2, &doomed));
    REQUIRE(rrskin_crowd_destroy(doomed));
    check(rrskin_crowd_set_bones(doomed, 0, poses, 2 * info.bones * 12) == RRSKIN_STATUS_ERROR_INVALID_HANDLE,
          "use after destroy is caught");
    check(rrskin_crowd_destroy(doomed) == RRSKIN_STATUS_ERROR_INVALID_HANDLE, "double destroy is caught");
    rrskin_crowd reused;
    REQUIRE(rrskin_crowd_create(model, 1, &reused)); /* may reuse the slot: the stale handle must still fail */
    check(reused.id != doomed.id && rrskin_crowd_destroy(doomed) == RRSKIN_STATUS_ERROR_INVALID_HANDLE,
          "a stale handle does not reach the slot's new crowd");
    REQUIRE(rrskin_crowd_destroy(reused));
    rrskin_context as_context = {crowd.id};
    check(rrskin_context_destroy(as_context) == RRSKIN_STATUS_ERROR_INVALID_HANDLE,
          "a crowd handle is not a context handle");
    check(rrskin_crowd_create(model, 0, &doomed) == RRSKIN_STATUS_ERROR_OUT_OF_RANGE, "an empty crowd");

    /* --- Teardown: rrskin first, then the engine's objects. --- */
    REQUIRE(rrskin_crowd_destroy(crowd));
    REQUIRE(rrskin_model_destroy(model));
    REQUIRE(rrskin_context_destroy(context));
    for (int i = 0; i < IN_FLIGHT; i++) {
        vkDestroyFence(device, fences[i], NULL);
        vkDestroyBuffer(device, copies[i], NULL);
        vkFreeMemory(device, copy_memory[i], NULL);
    }
    vkDestroyCommandPool(device, pool, NULL);
    vkDestroyDevice(device, NULL);
    destroy_messenger(instance, messenger, NULL);
    vkDestroyInstance(instance, NULL);
    check(validation_messages == 0, "no validation messages");
    free(poses);
    free(expected);
    free(expected_tangents);
    printf("%d passed, %d failed\n", passed, failed);
    return failed == 0 ? 0 : 1;
}
