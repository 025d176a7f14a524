use std::process::ExitCode;

/// Lists the Vulkan devices, and for each the driver profile glint renders
/// with there (`gpu::driver`).
pub fn run() -> anyhow::Result<ExitCode> {
    let devices = glint::gpu::list_devices().map_err(glint::Error::from)?;
    if devices.is_empty() {
        return Err(glint::Error::from(glint::gpu::GpuError::NoDevice).into());
    }
    println!(
        "{:<6} {:<40} {:<15} {:<8} driver",
        "index", "name", "type", "api"
    );
    for d in &devices {
        println!(
            "{:<6} {:<40} {:<15} {:<8} {}",
            d.index, d.name, d.device_type, d.api_version, d.driver
        );
    }
    for d in &devices {
        let settings: Vec<String> = d
            .profile
            .decisions()
            .iter()
            .map(|(what, value)| format!("{what} {value}"))
            .collect();
        println!(
            "profile {}: {}: {}",
            d.index,
            d.profile.kind,
            settings.join(", ")
        );
    }
    Ok(ExitCode::SUCCESS)
}
