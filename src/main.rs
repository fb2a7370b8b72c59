//! The `wavetrace` command; everything but argument parsing is in the library.

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = wavetrace::cli::Cli::parse();
    match wavetrace::cli::run(cli).map_err(anyhow::Error::from) {
        Ok(code) => code,
        Err(e) => {
            // The library's errors already say which file, line and field.
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
