//! The `glint` command line. Library errors become exit codes here:
//! 0 success, 2 bad scene input (or bad flags, from clap), 3 no Vulkan device
//! for `--backend gpu`, 1 anything else.

mod cli;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    // Output into a closed pipe (`glint info S | head -1`) ends the process
    // quietly, as for other Unix tools, instead of panicking in println!.
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE before any thread
    // starts; nothing else here relies on it being ignored.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    // An interrupted image write leaves no `.part` file behind: a signal
    // ends the process without running drops, so the handler removes them.
    // 130 = 128 + SIGINT, the shell's convention.
    let _ = ctrlc::set_handler(|| {
        glint::images::framebuffer::remove_partial_files();
        std::process::exit(130);
    });
    let args = cli::Cli::parse();
    let hint = args.no_device_hint();
    match cli::run(args) {
        Ok(code) => code,
        Err(err) => {
            eprintln!("error: {err:#}");
            let code = err
                .downcast_ref::<glint::Error>()
                .map_or(1, glint::Error::exit_code);
            if code == 3 {
                if let Some(hint) = hint {
                    eprintln!("hint: {hint}");
                }
            }
            ExitCode::from(code as u8)
        }
    }
}
