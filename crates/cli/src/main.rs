//! `facemimic`: the command-line tool (thin glue over the library).

#[cfg(not(target_arch = "wasm32"))]
mod build;
#[cfg(not(target_arch = "wasm32"))]
mod clone;
#[cfg(not(target_arch = "wasm32"))]
mod fit;
#[cfg(not(target_arch = "wasm32"))]
mod inspect;
#[cfg(not(target_arch = "wasm32"))]
mod landmark;
#[cfg(not(target_arch = "wasm32"))]
mod project;
#[cfg(not(target_arch = "wasm32"))]
mod render;

/// Writes `text` and a newline to standard output. A reader that has gone away (`facemimic
/// inspect M.fmm | head`) is not an error: there is no one left to tell.
#[cfg(not(target_arch = "wasm32"))]
pub(crate) fn print_line(text: &str) -> facemimic::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match writeln!(out, "{text}").and_then(|()| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
            Err(facemimic::Error::Io(format!("standard output: {e}")))
        }
        _ => Ok(()),
    }
}

#[cfg(not(target_arch = "wasm32"))]
mod cli {
    use clap::{Parser, Subcommand};
    use std::process::ExitCode;

    /// Real-time facial expression cloning with Active Appearance Models.
    #[derive(Parser)]
    #[command(name = "facemimic", version, about, propagate_version = true)]
    struct Cli {
        #[command(subcommand)]
        command: Command,
    }

    #[derive(Subcommand)]
    enum Command {
        /// Build a person-specific AAM from landmarked images.
        Build(super::build::Args),
        /// Print a model's sizes and variances as JSON.
        Inspect(super::inspect::Args),
        /// Project an image with landmarks into a model: print its parameters as JSON.
        Project(super::project::Args),
        /// Render a model instance (the base face, or given parameters) to PNG.
        Render(super::render::Args),
        /// Clone a source face's expression onto a target model.
        Clone(super::clone::Args),
        /// Fit (track) a model through a sequence of frames.
        Fit(super::fit::Args),
        /// Find the most confident face in each image and write its 68 landmarks (STEM.pts).
        Landmark(super::landmark::Args),
    }

    /// Command-line mistakes in one line: clap's message, the usage, and a hint. Help and
    /// version requests print as clap renders them.
    fn usage_error(e: clap::Error) -> ExitCode {
        use clap::error::ErrorKind;
        if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) {
            let _ = e.print();
            return ExitCode::SUCCESS;
        }
        // The subcommand named on the command line, for the hint.
        let sub = std::env::args().nth(1).filter(|a| {
            ["build", "inspect", "project", "render", "clone", "fit"].contains(&a.as_str())
        });
        let hint = match sub {
            Some(ref s) => format!("facemimic {s} --help"),
            None => "facemimic --help".to_string(),
        };
        let line = if e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
            match sub {
                Some(_) => "a required argument is missing".to_string(),
                None => {
                    "no command given (build, inspect, project, render, clone or fit)".to_string()
                }
            }
        } else {
            one_line_usage(&e.render().to_string())
        };
        eprintln!("facemimic: error: {line}; see {hint}");
        ExitCode::from(2)
    }

    /// Folds clap's multi-line error (message, tips, usage) into one line.
    fn one_line_usage(text: &str) -> String {
        let mut message = String::new();
        let mut usage = String::new();
        for line in text.lines().map(str::trim).filter(|l| !l.is_empty()) {
            if let Some(u) = line.strip_prefix("Usage:") {
                usage = u.trim().to_string();
            } else if line.starts_with("For more information") {
            } else if line.starts_with("tip:") {
                let tip = line.trim_start_matches("tip:").trim();
                message.push_str(&format!(" ({tip})"));
            } else if let Some(m) = line.strip_prefix("error:") {
                message.push_str(m.trim());
            } else if !usage.is_empty() {
                usage.push(' ');
                usage.push_str(line);
            } else {
                message.push(' ');
                message.push_str(line);
            }
        }
        let mut out = message;
        if !usage.is_empty() {
            out.push_str(&format!("; usage: {usage}"));
        }
        out
    }

    pub fn main() -> ExitCode {
        // Nothing should panic; if something does, say so in one line, not a backtrace.
        std::panic::set_hook(Box::new(|info| {
            let msg = info
                .payload()
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| info.payload().downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown".into());
            eprintln!("facemimic: internal error: {msg}");
        }));
        let cli = match Cli::try_parse() {
            Ok(cli) => cli,
            Err(e) => return usage_error(e),
        };
        let result = match cli.command {
            Command::Build(a) => super::build::run(a),
            Command::Inspect(a) => super::inspect::run(a),
            Command::Project(a) => super::project::run(a),
            Command::Render(a) => super::render::run(a),
            Command::Clone(a) => super::clone::run(a),
            Command::Fit(a) => super::fit::run(a),
            Command::Landmark(a) => super::landmark::run(a),
        };
        match result {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("facemimic: error: {}", e.to_string().replace('\n', " "));
                ExitCode::from(1)
            }
        }
    }
}

#[cfg(not(target_arch = "wasm32"))]
fn main() -> std::process::ExitCode {
    cli::main()
}

#[cfg(target_arch = "wasm32")]
fn main() {}
