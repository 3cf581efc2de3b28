//! The `sinterdem` command line. Run `sinterdem --help`. The whole command line lives in the
//! library ([`sinterdem::cli::main`]) so that the Python wheel's `sinterdem` command is this one.

use std::process::ExitCode;

fn main() -> ExitCode {
    // SIGINT/SIGTERM end a heat or compact run after its current step with its outputs written;
    // a second signal ends the process at once
    if let Err(e) = sinterdem::interrupt::install_handlers() {
        eprintln!("warning: signal handlers not installed ({e}): Ctrl-C ends a run without its summary");
    }
    ExitCode::from(u8::try_from(sinterdem::cli::main(std::env::args_os())).unwrap_or(1))
}
