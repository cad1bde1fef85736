//! What can go wrong reading or writing a recording; every error names the file.

use std::path::{Path, PathBuf};

/// An error of [`super::Recorder`] or [`super::Replay`], one line naming the file.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    #[error("{}: {cause}", path.display())]
    Io {
        path: PathBuf,
        cause: std::io::Error,
    },
    #[error("{}: {cause}", path.display())]
    Mcap {
        path: PathBuf,
        cause: mcap::McapError,
    },
    #[error("{}: {message}", path.display())]
    Invalid { path: PathBuf, message: String },
    /// A message that does not decode, before the file and topic are known.
    #[error("{0}")]
    Decode(String),
}

impl DatasetError {
    pub(crate) fn decode(message: impl Into<String>) -> Self {
        Self::Decode(message.into())
    }

    pub(crate) fn io(path: &Path) -> impl FnOnce(std::io::Error) -> Self + '_ {
        move |cause| Self::Io {
            path: path.to_owned(),
            cause,
        }
    }

    pub(crate) fn mcap(path: &Path) -> impl FnOnce(mcap::McapError) -> Self + '_ {
        move |cause| Self::Mcap {
            path: path.to_owned(),
            cause,
        }
    }

    pub(crate) fn invalid(path: &Path, message: impl Into<String>) -> Self {
        Self::Invalid {
            path: path.to_owned(),
            message: message.into(),
        }
    }
}
