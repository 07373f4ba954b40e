//! `ratf tune`: identify the wheel motors from open-loop PWM steps ([`motors`]: in the
//! simulator or from the original tuning node's CSV logs) and tune the Mega's wheel PI from
//! the identified model ([`gains`]). The fitting is in [`ratf_core::identification`]; these
//! apps collect the data, report, plot ([`svg`]) and write the configuration.

pub mod cli;
pub mod gains;
pub mod motors;
pub mod robot;
pub mod svg;
