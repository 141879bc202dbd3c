//! Why settings text, a control file or one of their values is refused. Each
//! error names the value and what would be accepted instead; none of them
//! touches a file.

use holodeck_protocol::{SectionError, SectionTextError};

/// A byte size (`64M`, `1.5G`) that does not parse.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SizeError {
    /// A letter other than K, M, G or T after the number.
    #[error("size {0:?} has an unknown unit (use K, M, G or T)")]
    UnknownUnit(String),
    /// No number before the unit.
    #[error("size {0:?} is not a number with an optional K/M/G/T unit")]
    NotANumber(String),
    /// A negative, NaN or infinite number.
    #[error("size {0:?} must be a non-negative number")]
    Negative(String),
    /// More bytes than 64 bits count.
    #[error("size {0:?} is more bytes than 64 bits can count")]
    TooLarge(String),
}

/// A duration (`90s`, `15m`, `2h`) that does not parse.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DurationError {
    /// No number before the unit.
    #[error("duration {0:?} is not a number with an optional s/m/h unit")]
    NotANumber(String),
    /// A negative, NaN or infinite number.
    #[error("duration {0:?} must be non-negative")]
    Negative(String),
    /// Longer than a duration can hold (about 584 billion years).
    #[error("duration {0:?} is too long")]
    TooLong(String),
}

/// A settings value that does not parse.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ValueError {
    /// CACHE or DISKSPACE.
    #[error(transparent)]
    Size(#[from] SizeError),
    /// TIME or REPORT.
    #[error(transparent)]
    Duration(#[from] DurationError),
    /// SECTION (boxed: a section error holds all its numbers).
    #[error(transparent)]
    Section(Box<SectionTextError>),
    /// OBSTRUCTIONS or VDISTANCE.
    #[error("{0:?} is not a boolean (use true or false)")]
    Bool(String),
    /// GRID.
    #[error("grid length {0:?} must be a positive finite number")]
    GridLength(String),
    /// SCENE.
    #[error("scene identity {0:?} must be 1-256 letters, digits or :._-+/= (a content hash)")]
    Scene(String),
}

/// A problem in settings text or a control file, with its line where known.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SettingsError {
    /// A line could not be understood.
    #[error("line {line}: {message}")]
    Line {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A value on a line of settings text does not parse.
    #[error("line {line}: {error}")]
    Value {
        /// 1-based line number.
        line: usize,
        /// Why (part of this message, not a separate cause).
        error: ValueError,
    },
    /// A value of a control file (or of settings built in code) is invalid.
    #[error("{key}: {error}")]
    Key {
        /// The key, as written in a control file.
        key: &'static str,
        /// Why (part of this message, not a separate cause).
        error: ValueError,
    },
    /// A section is invalid; the message names the control file key the
    /// problem is in (`origin`, `axes[0]`, `grid`), where it is in one.
    #[error("section {index}{key}: {error}", key = error.field().map(|f| format!(" {}", f.toml_key())).unwrap_or_default())]
    Section {
        /// Index of the section.
        index: usize,
        /// Why (part of this message, not a separate cause).
        error: SectionError,
    },
    /// The holodeck has no section.
    #[error("no section is defined: a holodeck needs at least one (SECTION= line, or [[section]] in a control file)")]
    NoSections,
    /// The TOML could not be parsed.
    #[error("{0}")]
    Toml(String),
}

impl From<SectionTextError> for ValueError {
    fn from(e: SectionTextError) -> Self {
        ValueError::Section(Box::new(e))
    }
}
