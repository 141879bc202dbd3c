//! Errors of the Radiance reader: every one names the file and line where the
//! reader stopped, and the token or primitive at fault when there is one.

use std::fmt;
use std::path::PathBuf;

/// A place in a Radiance file: the file and a 1-based line.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Location {
    /// The file.
    pub path: PathBuf,
    /// Line number, counting from 1.
    pub line: u32,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "{}:{}", self.path.display(), self.line)
    }
}

/// Why a Radiance file was refused, and where.
#[derive(Debug, thiserror::Error)]
#[error("{at}: {kind}")]
pub struct RadError {
    /// Where the reader stopped.
    pub at: Location,
    /// What is wrong (boxed: errors stay small on the happy path).
    pub kind: Box<RadErrorKind>,
}

/// What is wrong with a Radiance file.
#[derive(Debug, thiserror::Error)]
pub enum RadErrorKind {
    /// The file ends inside a primitive.
    #[error("the file ends inside {what}")]
    Truncated {
        /// What was being read (`the arguments of polygon "floor"`).
        what: String,
    },
    /// An argument count that is not a non-negative integer.
    #[error("{token:?} is not an argument count (a non-negative integer) in {what}")]
    BadCount {
        /// The token read.
        token: String,
        /// The primitive being read.
        what: String,
    },
    /// An argument count beyond what the reader takes (a guard against
    /// files that would make it allocate without bound).
    #[error("{count} {group} arguments in {what} is more than the {max} this reader takes")]
    TooManyArguments {
        /// The count given.
        count: u64,
        /// `string`, `integer` or `real`.
        group: &'static str,
        /// The most accepted.
        max: u64,
        /// The primitive being read.
        what: String,
    },
    /// A real argument that is not a finite number.
    #[error("{token:?} is not a finite number (a real argument of {what})")]
    NotANumber {
        /// The token read.
        token: String,
        /// The primitive being read.
        what: String,
    },
    /// An integer argument that is not an integer.
    #[error("{token:?} is not an integer (an integer argument of {what})")]
    NotAnInteger {
        /// The token read.
        token: String,
        /// The primitive being read.
        what: String,
    },
    /// A word longer than any name or number a scene needs.
    #[error("a word of more than {max} bytes")]
    WordTooLong {
        /// The most accepted.
        max: usize,
    },
    /// A primitive with the wrong number of arguments for its type.
    #[error("{what} takes {expected}; it has {got}")]
    ArgumentCount {
        /// The primitive.
        what: String,
        /// What its type takes (`4 reals`).
        expected: &'static str,
        /// What it has.
        got: String,
    },
    /// A modifier name that no earlier primitive defines.
    #[error("modifier {name:?} is not defined before this line")]
    UndefinedModifier {
        /// The name.
        name: String,
    },
    /// A modifier named `void` or `inherit`, names with a meaning of their own.
    #[error("{name:?} cannot name a modifier: it has a meaning of its own")]
    ReservedName {
        /// The name.
        name: String,
    },
    /// A primitive type Radiance does not have.
    #[error("unknown primitive type {kind:?}")]
    UnknownType {
        /// The type.
        kind: String,
    },
    /// A Radiance surface or volume this reader does not read.
    #[error("{kind} {name:?} is not supported: {why}")]
    UnsupportedSurface {
        /// The type.
        kind: String,
        /// Its identifier.
        name: String,
        /// Why, and what to do instead.
        why: &'static str,
    },
    /// A surface whose material is of a type this reader does not read.
    #[error("{what} uses material {material:?} of type {kind}, which is not supported (defined at {defined_at})")]
    UnsupportedMaterial {
        /// The surface.
        what: String,
        /// The material's name.
        material: String,
        /// The material's type.
        kind: String,
        /// Where the material is defined.
        defined_at: Location,
    },
    /// Arguments that describe no surface or material (a zero radius, a
    /// zero-length axis, an index of refraction below 1).
    #[error("{what}: {message}")]
    BadArguments {
        /// The primitive.
        what: String,
        /// What is wrong.
        message: String,
    },
    /// A distant `source` that the scene's sky cannot show.
    #[error("{what}: {message}")]
    Source {
        /// The source.
        what: String,
        /// Why.
        message: String,
    },
    /// A `!` command other than the ones read directly.
    #[error(
        "command {command:?} is not supported (only xform and genbox are read); run it and put its output in the file"
    )]
    UnsupportedCommand {
        /// The command's name.
        command: String,
    },
    /// A `!xform` or `!genbox` line that cannot be read.
    #[error("{command}: {message}")]
    BadCommand {
        /// The command's name.
        command: String,
        /// What is wrong.
        message: String,
    },
    /// A file that a command names could not be read.
    #[error("cannot read {file}: {source}")]
    Include {
        /// The file.
        file: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A file that a command names is not a regular file of sane size.
    #[error("cannot read {file}: {message}")]
    IncludeRefused {
        /// The file.
        file: PathBuf,
        /// Why.
        message: String,
    },
    /// A file that includes itself, directly or through others.
    #[error("{file} includes itself (through {chain})")]
    IncludeCycle {
        /// The file.
        file: PathBuf,
        /// The files on the way, outermost first.
        chain: String,
    },
    /// Includes nested deeper than the reader follows.
    #[error("files nested more than {max} deep")]
    TooDeep {
        /// The deepest nesting followed.
        max: usize,
    },
    /// More included files in all than the reader reads.
    #[error("more than {max} included files in all")]
    TooManyIncludes {
        /// The most read.
        max: usize,
    },
}

impl RadError {
    /// An error of `kind` at `at`.
    pub(super) fn new(at: &Location, kind: RadErrorKind) -> RadError {
        RadError {
            at: at.clone(),
            kind: Box::new(kind),
        }
    }
}
