//! benchbus: a Modbus RTU master for lab automation.
//!
//! Layers, from the wire up: [`codec`] (sans-IO frames), [`timing`] (character time, t3.5),
//! [`transport`] (byte pipes), [`bus`] (one transaction at a time, retries, pacing, stats),
//! [`device`] (register tables and typed device APIs).
//! The PyO3 bindings live in `python` behind the `python` cargo feature; without it the crate
//! is plain Rust.
#![deny(missing_docs)]

pub mod bus;
pub mod codec;
pub mod device;
pub mod error;
pub mod timing;
pub mod transport;

#[cfg(feature = "python")]
mod python;

pub use bus::{Bus, BusConfig, CancelToken, Stats, TxOptions};
pub use error::{Error, Result};
pub use timing::{LineFormat, Parity};
