//! Simulated statistics of the ring ([`RingStats`]): words, packets and busy clocks per channel,
//! queue high-water marks, traffic and token waiting per node, and totals. Only simulated
//! quantities; nothing here depends on the host.

use pxpl5_sim::{Cycles, Tick};

/// Everything [`crate::Ring::stats`] reports, as of [`crate::Ring::now`].
#[derive(Clone, Debug, PartialEq)]
pub struct RingStats {
    /// The ring's current time.
    pub now: Tick,
    /// Whole channel clocks elapsed by `now` (the denominator of every utilisation).
    pub elapsed: Cycles,
    /// Per channel, indexed by channel number.
    pub channels: Vec<ChannelStats>,
    /// Per node, indexed by position.
    pub nodes: Vec<NodeStats>,
    pub total: TotalStats,
}

/// One channel's traffic. Words and packets count packets that have *started* on the channel
/// (a packet in transmission counts whole); busy clocks count only clocks already elapsed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ChannelStats {
    /// Header words carried (`header_words` per packet).
    pub header_words: u64,
    /// Payload words carried.
    pub payload_words: u64,
    /// Packets started.
    pub packets: u64,
    /// Messages whose final packet travelled on this channel.
    pub messages: u64,
    /// Clocks in which a sender was putting a word of a packet on this channel.
    pub busy: Cycles,
    /// `busy / elapsed`; 0 before the first clock has elapsed.
    pub utilisation: f64,
}

/// One node's traffic and queues.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct NodeStats {
    /// Most words (headers included) ever in the output queue.
    pub max_output_words: u64,
    /// Most words ever in the input queue (reserved for messages in flight plus delivered, not
    /// consumed).
    pub max_input_words: u64,
    /// Messages accepted by `send`.
    pub messages_sent: u64,
    /// Messages delivered to this node.
    pub messages_received: u64,
    /// Packets started from this node.
    pub packets_sent: u64,
    /// Payload words of the packets started from this node.
    pub payload_words_sent: u64,
    /// Payload words of the packets that have reached this node.
    pub payload_words_received: u64,
    /// Sum over this node's packets of the clocks from when the packet could first have gone
    /// (eligible and at the head of the output queue) to its start: waiting for a token
    /// (contention), including any time its destination's input queue was full.
    pub token_wait: Cycles,
}

/// Sums over channels and nodes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TotalStats {
    pub header_words: u64,
    pub payload_words: u64,
    pub packets: u64,
    pub messages_sent: u64,
    pub messages_delivered: u64,
    /// Payload words that have reached their destinations.
    pub payload_words_delivered: u64,
    /// Busy clocks summed over channels.
    pub busy: Cycles,
    /// `busy / (elapsed * channels)`: the fraction of the ring's word slots used.
    pub utilisation: f64,
    pub token_wait: Cycles,
}

/// `num / den` as a fraction; 0 when nothing has elapsed.
pub(crate) fn ratio(num: u64, den: u64) -> f64 {
    if den == 0 {
        0.0
    } else {
        num as f64 / den as f64
    }
}
