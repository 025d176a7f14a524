use std::process::ExitCode;

pub fn run() -> anyhow::Result<ExitCode> {
    let devices = glint::gpu::list_devices().map_err(glint::Error::from)?;
    if devices.is_empty() {
        return Err(glint::Error::from(glint::gpu::GpuError::NoDevice).into());
    }
    println!(
        "{:<6} {:<40} {:<15} {:<8} driver",
        "index", "name", "type", "api"
    );
    for d in devices {
        println!(
            "{:<6} {:<40} {:<15} {:<8} {}",
            d.index, d.name, d.device_type, d.api_version, d.driver
        );
    }
    Ok(ExitCode::SUCCESS)
}
