//! What making a run's or a sweep's files fails with: said with what was being done, and, where
//! the system refused, the kind of its refusal, by which the binary tells a path the user gave
//! that cannot hold a directory (theirs to change) from a failing disk.

use std::fmt;
use std::io;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The directory given holds another run's first file already.
    #[error("{0}")]
    Taken(String),
    /// Anything else: a file that cannot be read or written, a table or figure that cannot be
    /// made, a sweep's rows that do not fit its grid; `io` is the system's refusal, if it was one.
    #[error("{words}")]
    Failed { words: String, io: Option<io::ErrorKind> },
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    pub fn failed(words: String) -> Error {
        Error::Failed { words, io: None }
    }

    /// The system's refusal under this error, if there was one.
    pub fn io_kind(&self) -> Option<io::ErrorKind> {
        match self {
            Error::Taken(_) => Some(io::ErrorKind::AlreadyExists),
            Error::Failed { io, .. } => *io,
        }
    }

    /// The same failure, said after what was being done; the system's refusal under it kept.
    pub fn said_after(self, doing: impl fmt::Display) -> Error {
        Error::Failed {
            words: format!("{doing}: {self}"),
            io: self.io_kind(),
        }
    }

    /// Whether the directory given was another run's.
    pub fn is_taken(&self) -> bool {
        matches!(self, Error::Taken(_))
    }
}

impl From<io::Error> for Error {
    fn from(e: io::Error) -> Error {
        Error::Failed {
            words: e.to_string(),
            io: Some(e.kind()),
        }
    }
}

/// What the libraries that write the files and serve the live view refuse, as their own words.
macro_rules! refusals {
    ($($library:ty),*) => {$(
        impl From<$library> for Error {
            fn from(e: $library) -> Error {
                Error::Failed {
                    words: e.to_string(),
                    io: io_kind_of(&e),
                }
            }
        }
    )*};
}
refusals!(csv::Error, serde_json::Error, tokio_tungstenite::tungstenite::Error);

/// The kind of the system's refusal in `e`, if it is one or carries one.
fn io_kind_of(e: &(dyn std::error::Error + 'static)) -> Option<io::ErrorKind> {
    if let Some(io) = e.downcast_ref::<io::Error>() {
        return Some(io.kind());
    }
    if let Some(ours) = e.downcast_ref::<Error>() {
        return ours.io_kind();
    }
    e.source().and_then(io_kind_of)
}

/// A failure said as `format!` says it.
macro_rules! failed {
    ($($words:tt)*) => {
        $crate::error::Error::failed(format!($($words)*))
    };
}
pub(crate) use failed;

/// Returns a failure said as `format!` says it.
macro_rules! bail {
    ($($words:tt)*) => {
        return Err($crate::error::failed!($($words)*))
    };
}
pub(crate) use bail;

/// What failed, said after what was being done, as anyhow's `context` says it; the system's
/// refusal under it, if any, kept.
pub trait Context<T> {
    fn context(self, doing: impl fmt::Display) -> Result<T>;
    fn with_context<D: fmt::Display>(self, doing: impl FnOnce() -> D) -> Result<T>;
}

impl<T, E: std::error::Error + 'static> Context<T> for std::result::Result<T, E> {
    fn context(self, doing: impl fmt::Display) -> Result<T> {
        self.map_err(|e| Error::Failed {
            words: format!("{doing}: {e}"),
            io: io_kind_of(&e),
        })
    }

    fn with_context<D: fmt::Display>(self, doing: impl FnOnce() -> D) -> Result<T> {
        self.map_err(|e| Error::Failed {
            words: format!("{}: {e}", doing()),
            io: io_kind_of(&e),
        })
    }
}

impl<T> Context<T> for Option<T> {
    fn context(self, doing: impl fmt::Display) -> Result<T> {
        self.ok_or_else(|| Error::failed(doing.to_string()))
    }

    fn with_context<D: fmt::Display>(self, doing: impl FnOnce() -> D) -> Result<T> {
        self.ok_or_else(|| Error::failed(doing().to_string()))
    }
}
