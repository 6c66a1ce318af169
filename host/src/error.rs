//! The host's error: what went wrong, and where (file, line or pixel). `main` maps each
//! variant to an exit code in one place ([`Error::exit_code`]).

use std::fmt;
use std::path::{Path, PathBuf};

#[derive(Debug)]
pub enum Error {
    /// Bad user input in a file: malformed, unknown key, out of range, inconsistent.
    Input {
        file: PathBuf,
        location: Option<Location>,
        message: String,
    },
    /// A file could not be read or written.
    Io {
        file: PathBuf,
        source: std::io::Error,
    },
    /// The core refused the data (capacity, invalid value), with what we were doing.
    Core {
        context: String,
        source: relume_core::Error,
    },
    /// Bad command-line usage that clap could not catch.
    Usage(String),
}

/// Where in a file the problem is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Location {
    /// 1-based line (and column when known).
    Line { line: usize, column: Option<usize> },
    /// Pixel column `x` (0 = left), row `y` (0 = top).
    Pixel { x: u32, y: u32 },
}

impl Error {
    pub fn input(file: impl AsRef<Path>, message: impl Into<String>) -> Error {
        Error::Input {
            file: file.as_ref().to_path_buf(),
            location: None,
            message: message.into(),
        }
    }

    pub fn at_line(file: impl AsRef<Path>, line: usize, message: impl Into<String>) -> Error {
        Error::Input {
            file: file.as_ref().to_path_buf(),
            location: Some(Location::Line { line, column: None }),
            message: message.into(),
        }
    }

    pub fn at_pixel(file: impl AsRef<Path>, x: u32, y: u32, message: impl Into<String>) -> Error {
        Error::Input {
            file: file.as_ref().to_path_buf(),
            location: Some(Location::Pixel { x, y }),
            message: message.into(),
        }
    }

    pub fn io(file: impl AsRef<Path>, source: std::io::Error) -> Error {
        Error::Io {
            file: file.as_ref().to_path_buf(),
            source,
        }
    }

    pub fn core(context: impl Into<String>, source: relume_core::Error) -> Error {
        Error::Core {
            context: context.into(),
            source,
        }
    }

    /// The process exit code: 2 usage, 3 bad input, 4 I/O, 5 refused by the core (130, an
    /// interrupt, is `fsutil::INTERRUPTED_EXIT_CODE`).
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Usage(_) => 2,
            Error::Input { .. } => 3,
            Error::Io { .. } => 4,
            Error::Core { .. } => 5,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Input {
                file,
                location,
                message,
            } => {
                write!(f, "{}", file.display())?;
                match location {
                    Some(Location::Line {
                        line,
                        column: Some(c),
                    }) => write!(f, ":{line}:{c}")?,
                    Some(Location::Line { line, column: None }) => write!(f, ":{line}")?,
                    Some(Location::Pixel { x, y }) => write!(f, ": pixel (x {x}, y {y})")?,
                    None => {}
                }
                write!(f, ": {message}")
            }
            Error::Io { file, source } => write!(f, "{}: {source}", file.display()),
            Error::Core { context, source } => write!(f, "{context}: {source}"),
            Error::Usage(message) => write!(f, "{message}"),
        }
    }
}

impl std::error::Error for Error {}
