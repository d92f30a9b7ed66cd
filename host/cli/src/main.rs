//! The `dips` binary.

use std::process::ExitCode;

fn main() -> ExitCode {
    match dips_cli::main() {
        Ok(()) => ExitCode::SUCCESS,
        // The reader closed the pipe (`dips … | head -1`): its choice, not an error.
        Err(e) if dips_cli::output::is_broken_pipe(&e) => ExitCode::SUCCESS,
        // One line per cause, never a backtrace: these are the user's errors to act on.
        Err(e) => {
            dips_cli::output::note(&format!("error: {}", dips_cli::output::causes(&e)));
            ExitCode::FAILURE
        }
    }
}
