//! `dips-mujoco`: the `dips` command line with the MuJoCo hand registered. Every command and
//! flag is `dips`'s; `--hand mujoco` on `dips episode`, `dips eval`, `dips sim run` and
//! `dips bench sim` executes on the MuJoCo hand ([`MujocoHands`]). The plain `dips` binary runs
//! this one for `--hand mujoco`. See docs/mujoco.md.

use std::process::ExitCode;

use dips_mujoco::run::MujocoHands;

fn main() -> ExitCode {
    match dips_cli::main_with(&MujocoHands) {
        Ok(()) => ExitCode::SUCCESS,
        // The reader closed the pipe (`dips-mujoco … | head -1`): its choice, not an error.
        Err(e) if dips_cli::output::is_broken_pipe(&e) => ExitCode::SUCCESS,
        // One line per cause, as `dips` writes them.
        Err(e) => {
            dips_cli::output::note(&format!("error: {}", dips_cli::output::causes(&e)));
            ExitCode::FAILURE
        }
    }
}
