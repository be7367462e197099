//! An engine's own Vulkan instance (validation and synchronization validation on, its
//! messages collected), device and compute queue, for the tests that play an engine.

use ash::vk;
use rrskin::vk::EngineDevice;
use std::ffi::c_void;
use std::sync::Mutex;

unsafe extern "system" fn collect(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: the layer passes valid data; `user` is the engine's message list, alive until the
    // messenger is destroyed.
    let (data, messages) = unsafe { (&*data, &*(user as *const Mutex<Vec<String>>)) };
    // SAFETY: as above.
    let text = unsafe { data.message_as_c_str() }.map(|m| m.to_string_lossy().into_owned());
    messages
        .lock()
        .expect("not poisoned")
        .push(format!("{severity:?}: {text:?}"));
    vk::FALSE
}

pub struct Engine {
    pub entry: ash::Entry,
    pub instance: ash::Instance,
    pub debug: ash::ext::debug_utils::Instance,
    pub messenger: vk::DebugUtilsMessengerEXT,
    pub physical: vk::PhysicalDevice,
    pub device: ash::Device,
    pub family: u32,
    pub queue: vk::Queue,
}

impl Engine {
    pub fn new(messages: &Mutex<Vec<String>>) -> Engine {
        // SAFETY: test code driving Vulkan directly, as an engine would; every call gets valid
        // arguments and objects are destroyed in `destroy`.
        unsafe {
            let entry = ash::Entry::load().expect("Vulkan loader");
            let app = vk::ApplicationInfo::default().api_version(vk::API_VERSION_1_2);
            let layers = [c"VK_LAYER_KHRONOS_validation".as_ptr()];
            let exts = [ash::ext::debug_utils::NAME.as_ptr()];
            let enables = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
            let mut features =
                vk::ValidationFeaturesEXT::default().enabled_validation_features(&enables);
            let info = vk::InstanceCreateInfo::default()
                .application_info(&app)
                .enabled_layer_names(&layers)
                .enabled_extension_names(&exts)
                .push_next(&mut features);
            let instance = entry
                .create_instance(&info, None)
                .expect("instance with validation");
            let debug = ash::ext::debug_utils::Instance::new(&entry, &instance);
            let messenger_info = vk::DebugUtilsMessengerCreateInfoEXT::default()
                .message_severity(
                    vk::DebugUtilsMessageSeverityFlagsEXT::WARNING
                        | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR,
                )
                .message_type(
                    vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                        | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION,
                )
                .pfn_user_callback(Some(collect))
                .user_data(messages as *const _ as *mut c_void);
            let messenger = debug
                .create_debug_utils_messenger(&messenger_info, None)
                .expect("messenger");
            let physical = instance.enumerate_physical_devices().expect("devices")[0];
            let family = instance
                .get_physical_device_queue_family_properties(physical)
                .iter()
                .position(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE))
                .expect("compute queue") as u32;
            let prio = [1.0];
            let queues = [vk::DeviceQueueCreateInfo::default()
                .queue_family_index(family)
                .queue_priorities(&prio)];
            let device = instance
                .create_device(
                    physical,
                    &vk::DeviceCreateInfo::default().queue_create_infos(&queues),
                    None,
                )
                .expect("device");
            let queue = device.get_device_queue(family, 0);
            Engine {
                entry,
                instance,
                debug,
                messenger,
                physical,
                device,
                family,
                queue,
            }
        }
    }

    pub fn handles(&self) -> EngineDevice {
        EngineDevice {
            get_instance_proc_addr: self.entry.static_fn().get_instance_proc_addr,
            instance: self.instance.handle(),
            physical_device: self.physical,
            device: self.device.handle(),
            queue_family_index: self.family,
            queue: self.queue,
        }
    }

    pub fn destroy(self) {
        // SAFETY: the context and everything made from it are gone; the GPU is idle.
        unsafe {
            self.device.destroy_device(None);
            self.debug
                .destroy_debug_utils_messenger(self.messenger, None);
            self.instance.destroy_instance(None);
        }
    }
}

/// The entry points of the engine that a test's wrapping `vkGetInstanceProcAddr` forwards to,
/// set anew for each engine. Each [`Engine`] loads libvulkan through its own `ash::Entry`, and
/// dropping the entry unloads the library (and destroying the instance its layers): a pointer
/// kept from an earlier test's engine points into a library that is gone, or was mapped again
/// at an address that depends on what else the process mapped meanwhile. Kept once, in a
/// `OnceLock`, it crashed the suite now and then under load.
pub struct Current<T: Copy>(Mutex<Option<T>>);

impl<T: Copy> Current<T> {
    pub const fn new() -> Current<T> {
        Current(Mutex::new(None))
    }

    /// The engine now alive: its entry points replace the last engine's.
    pub fn set(&self, value: T) {
        *self.0.lock().unwrap_or_else(|p| p.into_inner()) = Some(value);
    }

    pub fn get(&self) -> T {
        self.0
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .expect("the test's engine set it")
    }
}
