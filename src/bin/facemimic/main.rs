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
mod project;
#[cfg(not(target_arch = "wasm32"))]
mod render;

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
        let cli = Cli::parse();
        let result = match cli.command {
            Command::Build(a) => super::build::run(a),
            Command::Inspect(a) => super::inspect::run(a),
            Command::Project(a) => super::project::run(a),
            Command::Render(a) => super::render::run(a),
            Command::Clone(a) => super::clone::run(a),
            Command::Fit(a) => super::fit::run(a),
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
