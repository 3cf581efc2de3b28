//! The `sinterdem` command line. Run `sinterdem --help`. The whole command line lives in the
//! library ([`sinterdem::cli::main`]) so that the Python wheel's `sinterdem` command is this one.

use std::process::ExitCode;

fn main() -> ExitCode {
    ExitCode::from(u8::try_from(sinterdem::cli::main(std::env::args_os())).unwrap_or(1))
}
