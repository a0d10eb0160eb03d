//! `penumbra bench`: run time against error.

use std::path::PathBuf;

use clap::Args;

use super::CliError;

#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Scene file (JSON); the built-in seed room if omitted.
    pub scene: Option<PathBuf>,
}

pub fn bench(_args: &BenchArgs) -> Result<(), CliError> {
    Err(CliError::other("bench: being written in this session"))
}
