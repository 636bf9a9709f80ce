//! The subset of Perfetto's trace protobuf messages that [`crate::PerfettoTrace`] writes, as
//! `prost` messages. Each field's number and type is that of the upstream definition in the
//! Perfetto repository (`protos/perfetto/trace/...`, path given per message), so that Perfetto's
//! trace processor and UI read the file; fields this crate does not write are left out, which
//! protobuf allows (a reader skips nothing and defaults the rest).
//!
//! Deriving the messages from these structs, rather than generating them from the `.proto`
//! files, needs neither `protoc` nor a build script, and compiles in seconds (the generated
//! `perfetto_protos` crate takes minutes). Upstream's `oneof`s become separate optional fields
//! here: the wire format is the same, and the writer sets at most one field of each.
//!
//! Upstream declares the messages `proto2`, where repeated scalars are not packed; the
//! repeated scalar fields here say `packed = "false"` to be encoded as upstream expects.

/// `protos/perfetto/trace/trace.proto`: `message Trace { repeated TracePacket packet = 1; }`.
/// A trace file is this message: a concatenation of length-delimited field-1 packets, which is
/// why a trace can be written one packet at a time.
#[derive(Clone, PartialEq, prost::Message)]
pub struct Trace {
    /// `repeated TracePacket packet = 1;`
    #[prost(message, repeated, tag = "1")]
    pub packet: Vec<TracePacket>,
}

/// `protos/perfetto/trace/trace_packet.proto`, `message TracePacket`.
#[derive(Clone, PartialEq, prost::Message)]
pub struct TracePacket {
    /// `optional uint64 timestamp = 8;` (nanoseconds of the default clock).
    #[prost(uint64, optional, tag = "8")]
    pub timestamp: Option<u64>,
    /// `uint32 trusted_packet_sequence_id = 10;` (in `oneof optional_trusted_packet_sequence_id`).
    #[prost(uint32, optional, tag = "10")]
    pub trusted_packet_sequence_id: Option<u32>,
    /// `TrackEvent track_event = 11;` (in `oneof data`).
    #[prost(message, optional, tag = "11")]
    pub track_event: Option<TrackEvent>,
    /// `optional InternedData interned_data = 12;`
    #[prost(message, optional, tag = "12")]
    pub interned_data: Option<InternedData>,
    /// `optional uint32 sequence_flags = 13;` ([`SEQ_INCREMENTAL_STATE_CLEARED`],
    /// [`SEQ_NEEDS_INCREMENTAL_STATE`]).
    #[prost(uint32, optional, tag = "13")]
    pub sequence_flags: Option<u32>,
    /// `bytes compressed_packets = 50;` (in `oneof data`): packets (a `Trace` message's bytes)
    /// compressed with deflate (zlib format); each such packet should be under 512 KB.
    #[prost(bytes = "vec", optional, tag = "50")]
    pub compressed_packets: Option<Vec<u8>>,
    /// `TrackDescriptor track_descriptor = 60;` (in `oneof data`).
    #[prost(message, optional, tag = "60")]
    pub track_descriptor: Option<TrackDescriptor>,
}

/// `TracePacket.SequenceFlags.SEQ_INCREMENTAL_STATE_CLEARED = 1`: interned data before this
/// packet is forgotten (set on the sequence's first packet).
pub const SEQ_INCREMENTAL_STATE_CLEARED: u32 = 1;
/// `TracePacket.SequenceFlags.SEQ_NEEDS_INCREMENTAL_STATE = 2`: the packet uses interned data.
pub const SEQ_NEEDS_INCREMENTAL_STATE: u32 = 2;

/// `protos/perfetto/trace/track_event/track_descriptor.proto`, `message TrackDescriptor`.
#[derive(Clone, PartialEq, prost::Message)]
pub struct TrackDescriptor {
    /// `optional uint64 uuid = 1;`
    #[prost(uint64, optional, tag = "1")]
    pub uuid: Option<u64>,
    /// `string name = 2;` (in `oneof static_or_dynamic_name`).
    #[prost(string, optional, tag = "2")]
    pub name: Option<String>,
    /// `optional uint64 parent_uuid = 5;`
    #[prost(uint64, optional, tag = "5")]
    pub parent_uuid: Option<u64>,
    /// `optional CounterDescriptor counter = 8;`: set, the track is a counter track.
    #[prost(message, optional, tag = "8")]
    pub counter: Option<CounterDescriptor>,
}

/// `protos/perfetto/trace/track_event/counter_descriptor.proto`, `message CounterDescriptor`:
/// none of its fields (built-in counter types, units) applies, so it is empty; its presence
/// makes a counter track.
#[derive(Clone, PartialEq, prost::Message)]
pub struct CounterDescriptor {}

/// `protos/perfetto/trace/track_event/track_event.proto`, `enum TrackEvent.Type`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, prost::Enumeration)]
#[repr(i32)]
pub enum EventType {
    /// `TYPE_UNSPECIFIED = 0;`
    Unspecified = 0,
    /// `TYPE_SLICE_BEGIN = 1;`
    SliceBegin = 1,
    /// `TYPE_SLICE_END = 2;`
    SliceEnd = 2,
    /// `TYPE_INSTANT = 3;`
    Instant = 3,
    /// `TYPE_COUNTER = 4;`
    Counter = 4,
}

/// `protos/perfetto/trace/track_event/track_event.proto`, `message TrackEvent`.
#[derive(Clone, PartialEq, prost::Message)]
pub struct TrackEvent {
    /// `repeated DebugAnnotation debug_annotations = 4;`
    #[prost(message, repeated, tag = "4")]
    pub debug_annotations: Vec<DebugAnnotation>,
    /// `optional Type type = 9;`
    #[prost(enumeration = "EventType", optional, tag = "9")]
    pub r#type: Option<i32>,
    /// `uint64 name_iid = 10;` (in `oneof name_field`): an interned [`EventName`].
    #[prost(uint64, optional, tag = "10")]
    pub name_iid: Option<u64>,
    /// `optional uint64 track_uuid = 11;`
    #[prost(uint64, optional, tag = "11")]
    pub track_uuid: Option<u64>,
    /// `int64 counter_value = 30;` (in `oneof counter_value_field`).
    #[prost(int64, optional, tag = "30")]
    pub counter_value: Option<i64>,
    /// `repeated fixed64 flow_ids = 47;`: flows that start or pass here.
    #[prost(fixed64, repeated, packed = "false", tag = "47")]
    pub flow_ids: Vec<u64>,
    /// `repeated fixed64 terminating_flow_ids = 48;`: flows that end here.
    #[prost(fixed64, repeated, packed = "false", tag = "48")]
    pub terminating_flow_ids: Vec<u64>,
}

/// `protos/perfetto/trace/interned_data/interned_data.proto`, `message InternedData`.
#[derive(Clone, PartialEq, prost::Message)]
pub struct InternedData {
    /// `repeated EventName event_names = 2;`
    #[prost(message, repeated, tag = "2")]
    pub event_names: Vec<EventName>,
    /// `repeated DebugAnnotationName debug_annotation_names = 3;`
    #[prost(message, repeated, tag = "3")]
    pub debug_annotation_names: Vec<DebugAnnotationName>,
}

/// `protos/perfetto/trace/track_event/track_event.proto`, `message EventName`.
#[derive(Clone, PartialEq, prost::Message)]
pub struct EventName {
    /// `optional uint64 iid = 1;`
    #[prost(uint64, optional, tag = "1")]
    pub iid: Option<u64>,
    /// `optional string name = 2;`
    #[prost(string, optional, tag = "2")]
    pub name: Option<String>,
}

/// `protos/perfetto/trace/track_event/debug_annotation.proto`, `message DebugAnnotationName`.
#[derive(Clone, PartialEq, prost::Message)]
pub struct DebugAnnotationName {
    /// `optional uint64 iid = 1;`
    #[prost(uint64, optional, tag = "1")]
    pub iid: Option<u64>,
    /// `optional string name = 2;`
    #[prost(string, optional, tag = "2")]
    pub name: Option<String>,
}

/// `protos/perfetto/trace/track_event/debug_annotation.proto`, `message DebugAnnotation`: an
/// event argument (the JSON's `args`).
#[derive(Clone, PartialEq, prost::Message)]
pub struct DebugAnnotation {
    /// `uint64 name_iid = 1;` (in `oneof name_field`): an interned [`DebugAnnotationName`].
    #[prost(uint64, optional, tag = "1")]
    pub name_iid: Option<u64>,
    /// `bool bool_value = 2;` (in `oneof value`).
    #[prost(bool, optional, tag = "2")]
    pub bool_value: Option<bool>,
    /// `uint64 uint_value = 3;` (in `oneof value`).
    #[prost(uint64, optional, tag = "3")]
    pub uint_value: Option<u64>,
    /// `int64 int_value = 4;` (in `oneof value`).
    #[prost(int64, optional, tag = "4")]
    pub int_value: Option<i64>,
    /// `string string_value = 6;` (in `oneof value`).
    #[prost(string, optional, tag = "6")]
    pub string_value: Option<String>,
    /// `string legacy_json_value = 9;` (in `oneof value`): arrays and objects, as JSON text.
    #[prost(string, optional, tag = "9")]
    pub legacy_json_value: Option<String>,
}
