//! Exit codes of a command that ran but must not say success (documented in
//! [`crate::cmd`] and docs/cli.md).

/// A command that ran but must not exit 0: its code and one line to say why.
#[derive(Debug, thiserror::Error)]
#[error("{message}")]
pub struct Exit {
    pub code: u8,
    pub message: String,
}

impl Exit {
    /// Some runs or checks failed.
    pub const FAILURES: u8 = 3;
    /// Interrupted by SIGINT (128 + 2, as shells report it).
    pub const INTERRUPTED: u8 = 130;

    pub fn failures(message: impl Into<String>) -> Self {
        Self {
            code: Self::FAILURES,
            message: message.into(),
        }
    }

    pub fn interrupted(message: impl Into<String>) -> Self {
        Self {
            code: Self::INTERRUPTED,
            message: message.into(),
        }
    }
}
