//! Formats: the frame codecs and decoder (single and triad), frame captures,
//! the recording sinks' messages, MCAP writer and reader, and ROS 2 bags.

#[path = "../support/mod.rs"]
mod support;

mod frame_capture;
mod frame_codec;
mod frame_decoder;
mod frame_known_answer;
mod frame_prop;
mod frame_triad;
mod ros2_bag;
mod sink_mcap;
mod sink_messages;
mod sink_reader;
