//! `facemimic fit` (being written by the fitting work).

use facemimic::{Error, Result};

#[derive(clap::Args)]
pub struct Args {}

pub fn run(_a: Args) -> Result<()> {
    Err(Error::Params("fit is not available yet".into()))
}
