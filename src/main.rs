//! The `glint` command line. Library errors become exit codes here:
//! 0 success, 2 bad scene input (or bad flags, from clap), 3 no Vulkan device
//! for `--backend gpu`, 1 anything else.

mod cli;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
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
