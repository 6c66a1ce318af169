//! The core's one error type: small, `Copy`, and displayable. The host adds the context
//! (file, line, pixel) that the core does not know.

use core::fmt;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Error {
    /// A fixed capacity would be exceeded: `what` names the constant of [`crate::config`].
    Capacity {
        what: &'static str,
        max: usize,
        needed: usize,
    },
    /// A lent buffer is smaller than the work needs.
    BufferTooSmall {
        what: &'static str,
        needed: usize,
        got: usize,
    },
    /// A value outside its valid range (NaN, negative, zero where positive is required...).
    InvalidValue { what: &'static str },
    /// An index (group, light, texture) that points past its table.
    BadIndex {
        what: &'static str,
        index: usize,
        len: usize,
    },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Error::Capacity { what, max, needed } => write!(
                f,
                "scene too large for the core: {what} is {max}, this scene needs {needed}"
            ),
            Error::BufferTooSmall { what, needed, got } => {
                write!(f, "buffer {what} too small: needs {needed}, got {got}")
            }
            Error::InvalidValue { what } => write!(f, "invalid value: {what}"),
            Error::BadIndex { what, index, len } => {
                write!(f, "{what} index {index} out of range (there are {len})")
            }
        }
    }
}

/// Returns `Err(Capacity)` when `needed > max`.
pub fn check_capacity(what: &'static str, max: usize, needed: usize) -> Result<(), Error> {
    if needed > max {
        Err(Error::Capacity { what, max, needed })
    } else {
        Ok(())
    }
}
