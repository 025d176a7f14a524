//! The `glint` command line. Library errors become exit codes here:
//! 0 success, 2 bad scene input (or bad flags, from clap), 3 no Vulkan device
//! for `--backend gpu`, 1 anything else.

mod cli;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    // An interrupted image write leaves no `.part` file behind: a signal
    // ends the process without running drops, so the handler removes them.
    // 130 = 128 + SIGINT, the shell's convention.
    let _ = ctrlc::set_handler(|| {
        glint::framebuffer::remove_partial_files();
        std::process::exit(130);
    });
    let args = cli::Cli::parse();
    match cli::run(args) {
        Ok(code) => code,
        Err(err) => {
            eprintln!("error: {err:#}");
            let code = err
                .downcast_ref::<glint::Error>()
                .map_or(1, glint::Error::exit_code);
            ExitCode::from(code as u8)
        }
    }
}
