//! [`RingError`]: every way a caller can misuse the ring (a bad config, an unknown node, a message
//! that can never fit, a full output queue to retry later). A model bug is a panic instead, never
//! one of these.

use pxpl5_sim::Tick;

use crate::{MessageId, NodeId};

/// What the ring refuses to do, and why.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum RingError {
    /// A [`pxpl5_config::RingConfig`] field (or the node count) the model cannot run with.
    #[error("bad ring config: {field} = {value}: {rule}")]
    BadConfig {
        /// Dotted path of the field (`ring.channels`, ...), or `nodes` for the node count.
        field: &'static str,
        /// The offending value, as written.
        value: String,
        /// What is allowed.
        rule: String,
    },
    /// A node number outside `0..nodes`.
    #[error("node {node} is not on the ring (it has nodes 0..{nodes})")]
    UnknownNode { node: NodeId, nodes: u32 },
    /// A node sent a message to itself: the ring has no path of zero hops.
    #[error("node {node} sent a message to itself")]
    MessageToSelf { node: NodeId },
    /// A message of no payload words.
    #[error("message from node {src} to node {dst} has zero words")]
    ZeroWords { src: NodeId, dst: NodeId },
    /// A message bigger (headers included) than a whole queue: it could never be sent, so
    /// retrying is pointless.
    #[error(
        "message of {words} words needs {needed} queue words with its headers, \
         more than a queue holds ({queue_words})"
    )]
    MessageTooLarge {
        words: u32,
        needed: u64,
        queue_words: u32,
    },
    /// The sender's output queue lacks room now; retry once [`crate::Ring::output_free_words`]
    /// is at least `needed` (see [`crate::Ring::next_event_tick`]).
    #[error("output queue of node {node} is full: the message needs {needed} words, {free} free")]
    OutputFull {
        node: NodeId,
        needed: u64,
        free: u64,
    },
    /// A call dated before the ring's current time.
    #[error("time {now} is before the ring's current time {ring_now}")]
    TimeWentBackwards { now: Tick, ring_now: Tick },
    /// A send dated after [`crate::Ring::HORIZON`].
    #[error("time {now} is beyond the ring's horizon {horizon}")]
    BeyondHorizon { now: Tick, horizon: Tick },
    /// No message with this id was ever sent.
    #[error("message {id} was never sent")]
    UnknownMessage { id: MessageId },
    /// The message has not been delivered yet, so its words cannot be consumed.
    #[error("message {id} has not been delivered yet")]
    NotDelivered { id: MessageId },
    /// The message's words were already consumed.
    #[error("message {id} was already consumed")]
    AlreadyConsumed { id: MessageId },
}
