//! Which adapter the GPU backend opens: hardware first, lavapipe when asked.

/// Which adapters a backend may use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Want {
    /// A hardware GPU only (`--backend auto`).
    Hardware,
    /// Any adapter, software ones (lavapipe) included (`--backend gpu`).
    Any,
}

fn is_hardware(t: wgpu::DeviceType) -> bool {
    matches!(
        t,
        wgpu::DeviceType::DiscreteGpu
            | wgpu::DeviceType::IntegratedGpu
            | wgpu::DeviceType::VirtualGpu
    )
}

/// Call first in `main`, before any thread starts (it may set an environment
/// variable). Without a desktop session (no XDG_RUNTIME_DIR: ssh, batch jobs,
/// CI), Mesa's Vulkan device-select layer tries to reach a Wayland compositor
/// to learn the default GPU and prints "XDG_RUNTIME_DIR is invalid or not
/// set" twice per run, although nothing is wrong. `find_adapter` ranks the
/// adapters itself, so the layer has nothing to add: switch it off then
/// (its documented switch, NODEVICE_SELECT).
pub fn quiet_mesa_without_session() {
    if std::env::var_os("XDG_RUNTIME_DIR").is_none()
        && std::env::var_os("NODEVICE_SELECT").is_none()
    {
        std::env::set_var("NODEVICE_SELECT", "1");
    }
}

/// The adapter a backend would use, or `None`.
pub fn find_adapter(want: Want) -> Option<wgpu::Adapter> {
    let instance =
        wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let mut adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
    // Discrete first, then integrated, virtual, software.
    adapters.sort_by_key(|a| match a.get_info().device_type {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Cpu => 3,
        wgpu::DeviceType::Other => 4,
    });
    adapters.into_iter().find(|a| {
        let t = a.get_info().device_type;
        is_hardware(t) || (want == Want::Any && t == wgpu::DeviceType::Cpu)
    })
}
