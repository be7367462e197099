//! The Vulkan context: either its own headless instance and device, or an engine's borrowed ones.
//!
//! Everything made from a context (buffers, GPU models, crowds, batches) holds an
//! `Arc<Shared>`, so the device, allocator and pipelines are destroyed only after the last of
//! them is gone: nothing can outlive what it was allocated from.

use super::device_ext::Physical;
use super::pipelines::Pipelines;
use super::requirements::{check_device, check_functions};
use crate::error::{Error, Result};
use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use std::ffi::{c_char, c_void, CStr};
use std::sync::{Arc, Mutex, MutexGuard, OnceLock};

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// Which physical device a headless context takes.
#[derive(Debug, Clone, Default, PartialEq)]
pub enum DeviceChoice {
    /// Discrete, then integrated, then virtual, then CPU (lavapipe) devices.
    #[default]
    Auto,
    /// The first device whose name contains this text (case-insensitive).
    NameContains(String),
    /// The n-th device in enumeration order.
    Index(usize),
}

/// How to create a context with its own instance and device ([`Context::new`]).
#[derive(Debug, Clone, Default)]
pub struct ContextDesc {
    pub device: DeviceChoice,
    /// Enable the Khronos validation layer with synchronization validation, and collect its
    /// warnings and errors (see [`Context::validation_messages`]). Fails if the layer is absent.
    pub validation: bool,
    /// Extra instance extensions, e.g. a window system's surface extensions for an application
    /// that presents with the runtime's device (the crowd sample's window).
    pub instance_extensions: Vec<&'static CStr>,
    /// Extra device extensions, e.g. `VK_KHR_swapchain`. Devices without all of them are not
    /// picked.
    pub device_extensions: Vec<&'static CStr>,
    /// Use at most this many storage buffers per shader stage, below the device's
    /// maxPerStageDescriptorStorageBuffers: tests run a device that holds only some models'
    /// passes.
    pub max_storage_buffers_per_stage: Option<u32>,
}

/// An engine's Vulkan objects, borrowed (never destroyed) by [`Context::from_engine`].
#[derive(Clone, Copy)]
pub struct EngineDevice {
    pub get_instance_proc_addr: vk::PFN_vkGetInstanceProcAddr,
    pub instance: vk::Instance,
    pub physical_device: vk::PhysicalDevice,
    pub device: vk::Device,
    pub queue_family_index: u32,
    pub queue: vk::Queue,
}

/// Device limits the runtime plans around.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    pub max_storage_buffer_range: u64,
    pub min_storage_buffer_offset_alignment: u64,
    pub max_workgroup_count: [u32; 3],
    /// The largest device-local heap: no crowd larger than this is attempted.
    pub device_local_bytes: u64,
    /// maxPerStageDescriptorStorageBuffers (or the context's lower setting): a crowd whose
    /// widest pass binds more is refused, and no pipeline is made for a pass that binds more.
    pub max_storage_buffers_per_stage: u32,
    /// The largest buffer the device can make and bind (`maxMemoryAllocationSize`, and
    /// `maxBufferSize` with maintenance4): each of a crowd's buffers must fit it.
    pub max_buffer_bytes: u64,
    /// Queue families of the physical device (the outputs may be released to any other).
    pub queue_family_count: u32,
    /// The queue's timestamp counter; `None` if it has no timestamps.
    pub timestamps: Option<TimestampClock>,
    /// The device is a CPU implementation (lavapipe): it pays a buffer load once per lane even
    /// where every lane of a workgroup reads the same address, which GPUs broadcast; passes that
    /// differ only in how they share such loads choose by it.
    pub cpu_device: bool,
}

/// A queue's timestamp counter: nanoseconds a tick, and how many of its low bits count
/// (`timestampValidBits`: 64 on most GPUs, 36 on some), past which it wraps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimestampClock {
    pub period_ns: f64,
    pub valid_bits: u32,
}

impl TimestampClock {
    /// Milliseconds from tick `start` to tick `end` (the later), also where the counter wrapped
    /// between them: the difference is taken modulo 2^valid_bits, so bits above those that
    /// count never enter it.
    pub fn ms_between(&self, start: u64, end: u64) -> f64 {
        let mask = match self.valid_bits {
            64.. => u64::MAX,
            bits => (1u64 << bits) - 1,
        };
        (end.wrapping_sub(start) & mask) as f64 * self.period_ns * 1e-6
    }
}

/// A shared handle to the Vulkan device the runtime uses.
#[derive(Clone)]
pub struct Context {
    pub(crate) shared: Arc<Shared>,
}

pub(crate) struct Shared {
    /// Keeps the Vulkan loader loaded for as long as the device is used.
    entry: ash::Entry,
    pub instance: ash::Instance,
    pub physical_device: vk::PhysicalDevice,
    pub device: ash::Device,
    pub queue_family_index: u32,
    pub queue_has_graphics: bool,
    queue: Mutex<vk::Queue>,
    allocator: Mutex<Option<Allocator>>,
    pub limits: Limits,
    pub device_name: String,
    pub pipelines: Pipelines,
    /// Own instance/device (destroyed in Drop) or borrowed (left alone).
    owned: Option<Owned>,
    /// The command buffer (with its pool and fence) of uploads and read-backs, kept and reset
    /// each time: allocating one per call cost a driver or layer allocation every time (the
    /// validation layer never frees its per-command-buffer state: the long soak grew by it).
    pub one_time: Mutex<OneTime>,
    /// The call that returned `VK_ERROR_DEVICE_LOST`, once one did: nothing is submitted after.
    lost: OnceLock<&'static str>,
}

#[derive(Default)]
pub(crate) struct OneTime {
    pool: vk::CommandPool,
    cmd: vk::CommandBuffer,
    fence: vk::Fence,
}

struct Owned {
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    /// Boxed so its address (the messenger's user data) is stable; freed after the messenger.
    messages: Box<Mutex<Vec<String>>>,
}

impl Context {
    /// Creates an instance and device of its own (headless unless `desc` asks for surface
    /// extensions).
    pub fn new(desc: &ContextDesc) -> Result<Context> {
        // SAFETY: loading the system Vulkan loader; the Entry keeps the library alive.
        let entry = unsafe { ash::Entry::load() }.map_err(|e| Error::Loader {
            message: e.to_string(),
        })?;
        let messages: Box<Mutex<Vec<String>>> = Box::default();
        let (instance, debug) = create_instance(&entry, desc, &messages)?;
        let owned = Owned { debug, messages };
        let picked = (|| {
            let physical = pick_device(&instance, &desc.device, &desc.device_extensions)?;
            let queue_family_index = pick_queue_family(physical)?;
            let device = physical.create_device(queue_family_index, &desc.device_extensions)?;
            Ok((physical.handle, queue_family_index, device))
        })();
        let (physical_device, queue_family_index, device) = match picked {
            Ok(picked) => picked,
            Err(e) => {
                // SAFETY: no device was created from the instance.
                unsafe { destroy_instance(&instance, owned) };
                return Err(e);
            }
        };
        // SAFETY: the queue family was created with one queue.
        let queue = unsafe { device.get_device_queue(queue_family_index, 0) };
        Self::finish(
            entry,
            instance,
            physical_device,
            device,
            (queue_family_index, queue),
            Some(owned),
            desc.max_storage_buffers_per_stage,
        )
    }

    /// Wraps an engine's instance, physical device, device and queue.
    ///
    /// # Safety
    /// The handles must be valid, belong together, and outlive the returned context and
    /// everything made from it; `get_instance_proc_addr` must be the loader's (or a layer's)
    /// `vkGetInstanceProcAddr` for `instance`. The queue must support compute. The runtime
    /// submits to the queue only during uploads and read-backs and [`super::Batch::run`]; the
    /// engine must not use the queue concurrently with those calls.
    ///
    /// Fails with `MissingFunction` if a function the runtime calls is NULL from the engine's
    /// loader, and with `NoDevice` / `DeviceLimit` if the device does not meet
    /// [`super::requirements`].
    pub unsafe fn from_engine(engine: EngineDevice) -> Result<Context> {
        // SAFETY: the function's contract.
        unsafe { check_functions(&engine) }?;
        let static_fn = ash::StaticFn {
            get_instance_proc_addr: engine.get_instance_proc_addr,
        };
        // SAFETY: the caller guarantees the handles and the function pointer are valid.
        let entry = unsafe { ash::Entry::from_static_fn(static_fn.clone()) };
        // SAFETY: as above.
        let instance = unsafe { ash::Instance::load(&static_fn, engine.instance) };
        // SAFETY: as above.
        let device = unsafe { ash::Device::load(instance.fp_v1_0(), engine.device) };
        // SAFETY: the engine's physical device is of its instance (the caller's guarantee).
        let families =
            unsafe { Physical::from_raw(&instance, engine.physical_device) }.queue_families();
        let family = families
            .get(engine.queue_family_index as usize)
            .ok_or(Error::OutOfRange {
                what: "queue family index",
                index: engine.queue_family_index as usize,
                count: families.len(),
            })?;
        if !family.queue_flags.contains(vk::QueueFlags::COMPUTE) {
            return Err(Error::NoDevice {
                reason: "the engine's queue family has no compute".into(),
            });
        }
        Self::finish(
            entry,
            instance,
            engine.physical_device,
            device,
            (engine.queue_family_index, engine.queue),
            None,
            None,
        )
    }

    fn finish(
        entry: ash::Entry,
        instance: ash::Instance,
        physical_device: vk::PhysicalDevice,
        device: ash::Device,
        (queue_family_index, queue): (u32, vk::Queue),
        owned: Option<Owned>,
        max_storage_buffers: Option<u32>,
    ) -> Result<Context> {
        // SAFETY: both callers pass a device of this instance: enumerated by `new`, or the
        // engine's under `from_engine`'s contract.
        let physical = unsafe { Physical::from_raw(&instance, physical_device) };
        let props = physical.properties();
        check_device(&props)?;
        // Both callers checked the index against these families.
        let family = physical.queue_families()[queue_family_index as usize];
        let limits = Limits {
            max_storage_buffer_range: props.limits.max_storage_buffer_range as u64,
            min_storage_buffer_offset_alignment: props.limits.min_storage_buffer_offset_alignment,
            max_workgroup_count: props.limits.max_compute_work_group_count,
            device_local_bytes: physical.device_local_bytes(),
            max_buffer_bytes: physical.max_buffer_bytes(),
            max_storage_buffers_per_stage: (props.limits.max_per_stage_descriptor_storage_buffers)
                .min(max_storage_buffers.unwrap_or(u32::MAX)),
            queue_family_count: physical.queue_families().len() as u32,
            timestamps: (family.timestamp_valid_bits > 0).then_some(TimestampClock {
                period_ns: props.limits.timestamp_period as f64,
                valid_bits: family.timestamp_valid_bits,
            }),
            cpu_device: props.device_type == vk::PhysicalDeviceType::CPU,
        };
        let device_name = props
            .device_name_as_c_str()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        // Build the shared state first so that Drop cleans up whatever follows if it fails.
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.clone(),
            device: device.clone(),
            physical_device,
            debug_settings: Default::default(),
            buffer_device_address: false,
            allocation_sizes: Default::default(),
        });
        let mut shared = Shared {
            entry,
            instance,
            physical_device,
            device,
            queue_family_index,
            queue_has_graphics: family.queue_flags.contains(vk::QueueFlags::GRAPHICS),
            queue: Mutex::new(queue),
            allocator: Mutex::new(None),
            limits,
            device_name,
            pipelines: Pipelines::default(),
            owned,
            one_time: Mutex::default(),
            lost: OnceLock::new(),
        };
        let allocator = allocator.map_err(|e| Error::Allocation {
            what: "the GPU allocator",
            message: e.to_string(),
        })?;
        *lock(&shared.allocator) = Some(allocator);
        shared.create_one_time()?;
        shared.pipelines = Pipelines::new(&shared.device, limits.max_storage_buffers_per_stage)?;
        Ok(Context {
            shared: Arc::new(shared),
        })
    }

    pub fn device_name(&self) -> &str {
        &self.shared.device_name
    }

    pub fn limits(&self) -> Limits {
        self.shared.limits
    }

    /// The Vulkan entry points the context was loaded with (to create a surface, say).
    pub fn entry(&self) -> &ash::Entry {
        &self.shared.entry
    }

    pub fn instance(&self) -> &ash::Instance {
        &self.shared.instance
    }

    pub fn physical_device(&self) -> vk::PhysicalDevice {
        self.shared.physical_device
    }

    pub fn device(&self) -> &ash::Device {
        &self.shared.device
    }

    pub fn queue_family_index(&self) -> u32 {
        self.shared.queue_family_index
    }

    /// Runs `f` with the context's queue locked: an application that submits or presents on
    /// the runtime's own queue does it here, so that it never races the runtime's uploads,
    /// read-backs and [`super::Batch::run`].
    pub fn with_queue<R>(&self, f: impl FnOnce(vk::Queue) -> R) -> R {
        f(*lock(&self.shared.queue))
    }

    /// `Err(DeviceLost)` once any call on the context's device returned
    /// `VK_ERROR_DEVICE_LOST`: the context and everything made from it can then only be dropped.
    pub fn check_lost(&self) -> Result<()> {
        self.shared.check_lost()
    }

    /// Bytes of device memory the context's allocator holds: (in allocations, in memory
    /// blocks reserved from the driver).
    pub fn device_memory_bytes(&self) -> (u64, u64) {
        match &*self.shared.allocator() {
            Some(a) => {
                let report = a.generate_report();
                (report.total_allocated_bytes, report.total_capacity_bytes)
            }
            None => (0, 0),
        }
    }

    /// Warnings and errors the validation layer reported so far (headless contexts created with
    /// `validation: true`; empty otherwise).
    pub fn validation_messages(&self) -> Vec<String> {
        match &self.shared.owned {
            Some(owned) => lock(&owned.messages).clone(),
            None => Vec::new(),
        }
    }
}

impl Shared {
    pub fn allocator(&self) -> MutexGuard<'_, Option<Allocator>> {
        lock(&self.allocator)
    }

    pub fn check_lost(&self) -> Result<()> {
        match self.lost.get() {
            Some(&call) => Err(Error::DeviceLost { call }),
            None => Ok(()),
        }
    }

    /// Passes `e` on, remembering a lost device.
    pub fn note(&self, e: Error) -> Error {
        if let Error::DeviceLost { call } = e {
            let _ = self.lost.set(call);
        }
        e
    }

    /// Makes the one-time command buffer, its pool and fence (each owned by `one_time` as soon
    /// as it exists, so that Drop destroys what was made if a later step fails).
    fn create_one_time(&self) -> Result<()> {
        let mut one = lock(&self.one_time);
        one.pool = self.create_command_pool(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER)?;
        let info = vk::CommandBufferAllocateInfo::default()
            .command_pool(one.pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: the pool was just made, and is externally synchronised by the mutex.
        one.cmd = unsafe { self.device.allocate_command_buffers(&info) }
            .map_err(Error::vk("vkAllocateCommandBuffers"))?[0];
        one.fence = self.create_fence()?;
        Ok(())
    }

    /// Records the one-time command buffer with `record`, submits it to the queue and waits for
    /// completion (uploads, read-backs).
    pub fn record_and_submit(
        &self,
        record: impl FnOnce(vk::CommandBuffer) -> Result<()>,
    ) -> Result<()> {
        let one = lock(&self.one_time);
        self.rerecord_and_submit(one.cmd, one.fence, record)
    }

    /// Resets `cmd`, records it with `record` for one submission, submits it and waits on
    /// `fence` (unsignalled). `cmd` must not be pending (every use waits for completion, or for
    /// the queue to idle after a failed wait) nor be recorded by anyone else meanwhile.
    pub fn rerecord_and_submit(
        &self,
        cmd: vk::CommandBuffer,
        fence: vk::Fence,
        record: impl FnOnce(vk::CommandBuffer) -> Result<()>,
    ) -> Result<()> {
        let begin = vk::CommandBufferBeginInfo::default()
            .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
        // SAFETY: `cmd` is not pending and recorded by no one else (the function's contract).
        unsafe {
            (self.device)
                .reset_command_buffer(cmd, vk::CommandBufferResetFlags::empty())
                .map_err(Error::vk("vkResetCommandBuffer"))?;
            (self.device.begin_command_buffer(cmd, &begin))
                .map_err(Error::vk("vkBeginCommandBuffer"))?;
        }
        let recorded = record(cmd);
        // SAFETY: as above, and begun.
        let ended =
            unsafe { self.device.end_command_buffer(cmd) }.map_err(Error::vk("vkEndCommandBuffer"));
        recorded?;
        ended?;
        self.submit_recorded(cmd, fence)
    }

    /// Submits one recorded command buffer, waits on `fence` (unsignalled) and resets it; fails
    /// at once on a lost device.
    fn submit_recorded(&self, cmd: vk::CommandBuffer, fence: vk::Fence) -> Result<()> {
        self.check_lost()?;
        let cmds = [cmd];
        let submit = [vk::SubmitInfo::default().command_buffers(&cmds)];
        let queue = lock(&self.queue);
        // SAFETY: the queue is externally synchronised by the mutex; cmd is executable; the
        // fence belongs to this device and is unsignalled.
        let result = unsafe {
            (self.device.queue_submit(*queue, &submit, fence))
                .map_err(Error::vk("vkQueueSubmit"))
                .and_then(|()| {
                    let waited = (self.device.wait_for_fences(&[fence], true, u64::MAX))
                        .map_err(Error::vk("vkWaitForFences"));
                    if waited.is_err() {
                        // The work may still execute: let it end before the caller frees or
                        // reuses what it reads (on a lost device this returns at once).
                        let _ = self.device.queue_wait_idle(*queue);
                    }
                    let reset = self.device.reset_fences(&[fence]);
                    waited.and(reset.map_err(Error::vk("vkResetFences")))
                })
        };
        result.map_err(|e| self.note(e))
    }
}

impl Drop for Shared {
    fn drop(&mut self) {
        // SAFETY: every object made from this context is gone (they hold the Arc); wait for the
        // GPU, then destroy in reverse order of creation.
        unsafe {
            let _ = self.device.device_wait_idle();
            self.pipelines.destroy(&self.device);
            let one = lock(&self.one_time);
            self.device.destroy_fence(one.fence, None);
            self.device.destroy_command_pool(one.pool, None);
        }
        // The allocator frees its memory blocks through the device: before the device goes.
        drop(lock(&self.allocator).take());
        if let Some(owned) = self.owned.take() {
            // SAFETY: we created device and instance; nothing else uses them any more.
            unsafe {
                self.device.destroy_device(None);
                destroy_instance(&self.instance, owned);
            }
        }
    }
}

/// # Safety
/// Nothing created from `instance` may still exist, except the messenger in `owned`.
unsafe fn destroy_instance(instance: &ash::Instance, owned: Owned) {
    if let Some((debug, messenger)) = &owned.debug {
        // SAFETY: the messenger was created from this instance.
        unsafe { debug.destroy_debug_utils_messenger(*messenger, None) };
    }
    // SAFETY: see the function's contract.
    unsafe { instance.destroy_instance(None) };
    drop(owned);
}

type Debug = Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>;

fn create_instance(
    entry: &ash::Entry,
    desc: &ContextDesc,
    messages: &Mutex<Vec<String>>,
) -> Result<(ash::Instance, Debug)> {
    let validation = desc.validation;
    let app = vk::ApplicationInfo::default()
        .application_name(c"rrskin")
        .engine_name(c"rrskin")
        .api_version(vk::API_VERSION_1_2);
    let mut layers = Vec::new();
    let mut extensions: Vec<*const c_char> = desc
        .instance_extensions
        .iter()
        .map(|e| e.as_ptr())
        .collect();
    if validation {
        // SAFETY: the entry holds the loaded Vulkan library; a global query needs nothing else.
        let available = unsafe { entry.enumerate_instance_layer_properties() }
            .map_err(Error::vk("vkEnumerateInstanceLayerProperties"))?;
        if !available
            .iter()
            .any(|l| l.layer_name_as_c_str() == Ok(VALIDATION_LAYER))
        {
            return Err(Error::MissingLayer {
                name: VALIDATION_LAYER.to_string_lossy().into(),
            });
        }
        layers.push(VALIDATION_LAYER.as_ptr());
        extensions.push(ash::ext::debug_utils::NAME.as_ptr());
    }
    let enabled = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
    let mut features = vk::ValidationFeaturesEXT::default().enabled_validation_features(&enabled);
    let messenger_info = || {
        vk::DebugUtilsMessengerCreateInfoEXT::default()
            .message_severity(
                vk::DebugUtilsMessageSeverityFlagsEXT::WARNING
                    | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR,
            )
            .message_type(
                vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                    | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                    | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
            )
            .pfn_user_callback(Some(on_validation_message))
            .user_data(messages as *const Mutex<Vec<String>> as *mut c_void)
    };
    // Chained into the instance info so that vkCreateInstance/vkDestroyInstance are covered.
    let mut instance_messenger = messenger_info();
    let mut info = vk::InstanceCreateInfo::default()
        .application_info(&app)
        .enabled_layer_names(&layers)
        .enabled_extension_names(&extensions);
    if validation {
        info = info
            .push_next(&mut features)
            .push_next(&mut instance_messenger);
    }
    // SAFETY: the entry holds the loaded library; the names, layers and chained structures the
    // create info points to live until the call returns.
    let instance =
        unsafe { entry.create_instance(&info, None) }.map_err(Error::vk("vkCreateInstance"))?;
    if !validation {
        return Ok((instance, None));
    }
    let debug = ash::ext::debug_utils::Instance::new(entry, &instance);
    // SAFETY: the instance has the extension enabled; `messages` outlives the messenger.
    match unsafe { debug.create_debug_utils_messenger(&messenger_info(), None) } {
        Ok(messenger) => Ok((instance, Some((debug, messenger)))),
        Err(result) => {
            // SAFETY: nothing else was created from the instance.
            unsafe { instance.destroy_instance(None) };
            Err(Error::vk("vkCreateDebugUtilsMessengerEXT")(result))
        }
    }
}

unsafe extern "system" fn on_validation_message(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: the layer passes valid callback data; `user` is the `Mutex<Vec<String>>` boxed in
    // `Owned`, which outlives the messenger.
    let (data, messages) = unsafe { (&*data, &*(user as *const Mutex<Vec<String>>)) };
    // SAFETY: as above; the message is a valid C string when non-null.
    let text = unsafe { data.message_as_c_str() }
        .map(|m| m.to_string_lossy().into_owned())
        .unwrap_or_default();
    lock(messages).push(format!("{severity:?}: {text}"));
    vk::FALSE
}

fn pick_device<'a>(
    instance: &'a ash::Instance,
    choice: &DeviceChoice,
    extensions: &[&CStr],
) -> Result<Physical<'a>> {
    let usable: Vec<(usize, Physical, vk::PhysicalDeviceProperties)> =
        Physical::enumerate(instance)?
            .into_iter()
            .enumerate()
            .filter(|(_, d)| pick_queue_family(*d).is_ok() && d.has_extensions(extensions))
            .map(|(i, d)| (i, d, d.properties()))
            .collect();
    let name_of = |p: &vk::PhysicalDeviceProperties| {
        p.device_name_as_c_str()
            .map(|s| s.to_string_lossy().to_lowercase())
            .unwrap_or_default()
    };
    let rank = |t: vk::PhysicalDeviceType| match t {
        vk::PhysicalDeviceType::DISCRETE_GPU => 0,
        vk::PhysicalDeviceType::INTEGRATED_GPU => 1,
        vk::PhysicalDeviceType::VIRTUAL_GPU => 2,
        vk::PhysicalDeviceType::CPU => 3,
        _ => 4,
    };
    let found = match choice {
        DeviceChoice::Auto => usable.iter().min_by_key(|(_, _, p)| rank(p.device_type)),
        DeviceChoice::NameContains(text) => usable
            .iter()
            .find(|(_, _, p)| name_of(p).contains(&text.to_lowercase())),
        DeviceChoice::Index(n) => usable.iter().find(|(i, _, _)| i == n),
    };
    found.map(|(_, d, _)| *d).ok_or_else(|| {
        let names: Vec<String> = usable
            .iter()
            .map(|(i, _, p)| format!("{i}: {}", name_of(p)))
            .collect();
        Error::NoDevice {
            reason: format!(
                "{choice:?} matches none of the devices with compute{} [{}]",
                if extensions.is_empty() {
                    String::new()
                } else {
                    format!(" and {extensions:?}")
                },
                names.join(", ")
            ),
        }
    })
}

/// A queue family with compute; one with graphics too is preferred so that the crowd sample can
/// draw from the outputs on the same queue.
fn pick_queue_family(device: Physical) -> Result<u32> {
    let families = device.queue_families();
    let compute = |f: &vk::QueueFamilyProperties| f.queue_flags.contains(vk::QueueFlags::COMPUTE);
    let both = vk::QueueFlags::COMPUTE | vk::QueueFlags::GRAPHICS;
    families
        .iter()
        .position(|f| f.queue_flags.contains(both))
        .or_else(|| families.iter().position(compute))
        .map(|i| i as u32)
        .ok_or(Error::NoDevice {
            reason: "no queue family with compute".into(),
        })
}

/// A poisoned lock only means another thread panicked while holding it; the data (handles,
/// message lists) stays consistent, so carry on rather than propagate the panic.
pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

#[cfg(test)]
mod tests {
    use super::TimestampClock;

    #[test]
    fn a_timestamp_difference_counts_only_the_valid_bits_across_a_wrap() {
        // 36 valid bits (some Intel GPUs) at 52.08 ns a tick: 2^36 ticks wrap in an hour.
        let clock = TimestampClock {
            period_ns: 52.08,
            valid_bits: 36,
        };
        let top = (1u64 << 36) - 10;
        assert!((clock.ms_between(top, 5) - 15.0 * 52.08e-6).abs() < 1e-12);
        assert!((clock.ms_between(100, 1100) - 1000.0 * 52.08e-6).abs() < 1e-12);
        // 64 bits: the plain difference.
        let wide = TimestampClock {
            period_ns: 1.0,
            valid_bits: 64,
        };
        assert_eq!(wide.ms_between(u64::MAX - 1, 2), 4.0 * 1e-6);
    }
}
