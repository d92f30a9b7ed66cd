//! Write an episode's report again from its `result.json`: `report.html` (with the 3D view)
//! and the plots over time, into the directory that holds it; the animation too with
//! `--render`. Used by `scripts/check-report-3d.sh`.
//!
//! `cargo run --release -p dips-report --example episode_report -- DIR [--render]`

use std::path::PathBuf;
use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let animate = args.iter().any(|a| a == "--render");
    let dirs: Vec<&String> = args.iter().filter(|a| !a.starts_with("--")).collect();
    let [dir] = dirs.as_slice() else {
        eprintln!("usage: episode_report DIR [--render]   (DIR holds an episode's result.json)");
        return ExitCode::from(2);
    };
    let dir = PathBuf::from(dir);
    let written = dips_report::Recording::read(&dir.join("result.json"))
        .and_then(|rec| dips_report::write_episode_report(&dir, &rec, animate, &mut |_, _| {}));
    match written {
        Ok(()) => {
            println!("{}", dir.join(dips_report::REPORT_HTML).display());
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
