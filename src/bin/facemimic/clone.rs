//! `facemimic clone` (being written by the cloning work).

use facemimic::{Error, Result};

#[derive(clap::Args)]
pub struct Args {}

pub fn run(_a: Args) -> Result<()> {
    Err(Error::Params("clone is not available yet".into()))
}
