//! The operator's web HMI: one page, served by `ratf sim`, `ratf run` and `ratf replay`
//! with `--hmi ADDR`, that shows what the robot believes at ≥ 10 updates a second and lets
//! a person with the token control the run from a phone or laptop on the robot's Wi-Fi.
//!
//! - [`tap::HmiTap`] is a runtime [`Tap`](ratf_core::runtime::Tap): it sees every step
//!   (the core, its outputs and events, the simulator's true pose) and publishes a
//!   [`snapshot::Snapshot`] to the [`hub::Hub`] every [`tap::PUBLISH_PERIOD`] of wall time.
//! - [`server`] is a blocking `tiny_http` server on its own threads (no async runtime in the
//!   robot's process): the page and its assets (embedded in the binary), the floor's
//!   geometry, the snapshot stream as Server-Sent Events, and the controls.
//! - [`commands`] turns a control request into an
//!   [`OperatorCommand`](ratf_core::runtime::OperatorCommand) sent through
//!   [`crate::devices::operator`] (so the core consumes it as an input and the recording
//!   keeps it), a round choice for the simulator, or a request to the replay player.
//! - [`auth`]: the token printed at start-up, compared in constant time.
//! - [`replay`]: the player behind `ratf replay FILE --hmi ADDR` (time slider, play/pause,
//!   speed, jump to an event): the recording's inputs folded through a core up to the chosen
//!   time.
//!
//! The core knows nothing of any of this.

pub mod auth;
pub mod commands;
pub mod floor;
pub mod hub;
pub mod replay;
pub mod server;
pub mod snapshot;
pub mod tap;
