//! The instance state as bytes: framing and checksum (used by every layer), and the
//! physics' part of the state.

pub mod bytes;
mod state_bytes;
