//! What was wrong with a message's bytes: the `source` of [`super::Error::Decode`].

/// What was wrong with a message's bytes (offsets are bytes from the start of
/// the message; for CDR, from the end of its 4-byte header). The readers add
/// the file, topic and message index ([`Error::Decode`]).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum WireError {
    /// Fewer bytes than a field needs.
    #[error(
        "message too short: {need} bytes needed at offset {offset}, {len} bytes in the message"
    )]
    Truncated {
        /// Where the field starts.
        offset: usize,
        /// Bytes the field needs.
        need: usize,
        /// Bytes in the message.
        len: usize,
    },
    /// A field whose value is not allowed (an encapsulation, a wire type, a
    /// length that does not fit).
    #[error("offset {offset}: {what}")]
    Malformed {
        /// Where the field starts.
        offset: usize,
        /// What was wrong.
        what: String,
    },
    /// A field of another type than the schema says, a missing field, or a
    /// message that is not what its schema says (protobuf, JSON).
    #[error("{what}")]
    Schema {
        /// What was expected and found.
        what: String,
    },
    /// A well-formed value that is not allowed (a non-finite pose, a zero
    /// quaternion).
    #[error("{what}")]
    Value {
        /// The value and why it is refused.
        what: String,
    },
}

impl WireError {
    /// A [`WireError::Malformed`] at `offset`.
    pub fn malformed(offset: usize, what: impl Into<String>) -> Self {
        WireError::Malformed {
            offset,
            what: what.into(),
        }
    }

    /// A [`WireError::Schema`].
    pub fn schema(what: impl Into<String>) -> Self {
        WireError::Schema { what: what.into() }
    }

    /// A [`WireError::Value`].
    pub fn value(what: impl Into<String>) -> Self {
        WireError::Value { what: what.into() }
    }

    /// The byte offset of the problem, when it has one.
    pub fn offset(&self) -> Option<usize> {
        match self {
            WireError::Truncated { offset, .. } | WireError::Malformed { offset, .. } => {
                Some(*offset)
            }
            WireError::Schema { .. } | WireError::Value { .. } => None,
        }
    }
}
