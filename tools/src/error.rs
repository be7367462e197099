//! One error type for what the tools' library calls can fail with, and its `Result` alias.

use crate::set::InputError;
use crate::train::TrainError;
use std::fmt;
use std::path::PathBuf;

#[derive(Debug)]
pub enum Error {
    /// A bad input file (example set, rig, point cache): which file and what is wrong.
    Input { source: InputError },
    /// Training could not finish.
    Train { source: TrainError },
    /// The runtime refused something: a model file, a Vulkan device.
    Runtime { source: rrskin::Error },
    /// A model evaluated against an example set of another mesh or skeleton.
    ModelMismatch {
        model: PathBuf,
        model_size: (usize, usize),
        set_size: (usize, usize),
    },
    /// An output that cannot be written.
    Output { path: PathBuf, problem: String },
    /// A baseline's precomputation failed (a linear system it cannot solve).
    Baseline {
        method: &'static str,
        problem: String,
    },
}

pub type Result<T> = std::result::Result<T, Error>;

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Input { source } => write!(f, "{source}"),
            Error::Train { source } => write!(f, "training: {source}"),
            Error::Runtime { source } => write!(f, "{source}"),
            Error::ModelMismatch {
                model,
                model_size,
                set_size,
            } => write!(
                f,
                "{}: the model has {} vertices and {} bones, the example set {} and {}",
                model.display(),
                model_size.0,
                model_size.1,
                set_size.0,
                set_size.1
            ),
            Error::Output { path, problem } => write!(f, "{}: {problem}", path.display()),
            Error::Baseline { method, problem } => write!(f, "{method}: {problem}"),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Input { source } => Some(source),
            Error::Train { source } => Some(source),
            Error::Runtime { source } => Some(source),
            _ => None,
        }
    }
}

impl From<InputError> for Error {
    fn from(source: InputError) -> Error {
        Error::Input { source }
    }
}

impl From<TrainError> for Error {
    fn from(source: TrainError) -> Error {
        Error::Train { source }
    }
}

impl From<rrskin::Error> for Error {
    fn from(source: rrskin::Error) -> Error {
        Error::Runtime { source }
    }
}
