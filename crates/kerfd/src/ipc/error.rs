//! Why a node, service or port of a machine's iceoryx2 services could not be made, as a
//! value: a caller tells "no daemon serves the machine" from "files of another user" from
//! "iceoryx2 refused" without reading the message.

/// Why a node, service or port of the machine's iceoryx2 services could not be made.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum IpcError {
    /// A node or service name iceoryx2 does not accept.
    #[error("{0}")]
    InvalidName(String),
    /// Files of the iceoryx2 tree belong to another user; `why` names the path, the owner
    /// and what to do.
    #[error("{action}: {why}")]
    PermissionDenied {
        /// What could not be done.
        action: String,
        /// The files, their owner and the remedy.
        why: String,
    },
    /// The service does not exist: no daemon serves the machine.
    #[error("{action}: the service does not exist")]
    NoService {
        /// What could not be done.
        action: String,
    },
    /// iceoryx2 refused for another reason, in its own words.
    #[error("{action}: {cause}")]
    Refused {
        /// What could not be done.
        action: String,
        /// iceoryx2's reason.
        cause: String,
    },
}

impl IpcError {
    /// iceoryx2's refusal of `action`, in its words.
    pub(crate) fn refused(action: &str, cause: impl std::fmt::Debug) -> IpcError {
        IpcError::Refused {
            action: action.to_string(),
            cause: format!("{cause:?}"),
        }
    }
}
