//! How `ratf run` joins the ROS 2 graph live: the options (always compiled, so the CLI
//! explains itself in a build without DDS) and the bridge as a [`Tap`], present only with
//! cargo feature `ros2`.

use ratf_core::config::Config;
use ratf_core::runtime::Tap;

use crate::devices::operator::OperatorSender;

/// The environment variable ROS 2 reads the DDS domain from.
pub const DOMAIN_ENV: &str = "ROS_DOMAIN_ID";

/// How the bridge joins the ROS 2 graph.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct BridgeOptions {
    /// The robot's namespace (`/robot1`; empty: none), so several robots share a domain.
    pub namespace: String,
    /// The DDS domain (`ROS_DOMAIN_ID`; 0 when unset).
    pub domain_id: u16,
    /// Talk on 127.0.0.1 only (nothing leaves the machine).
    pub loopback_only: bool,
    /// The operator lets `cmd_vel` drive the robot (manual mode).
    pub cmd_vel: bool,
}

impl BridgeOptions {
    /// The domain in `ROS_DOMAIN_ID`'s text `value` (0 when unset).
    pub fn parse_domain(value: Option<&str>) -> Result<u16, BridgeError> {
        match value {
            None => Ok(0),
            Some(text) => text
                .trim()
                .parse::<u16>()
                .ok()
                .filter(|d| *d <= 232)
                .ok_or_else(|| BridgeError::Domain(text.to_owned())),
        }
    }

    /// The domain from the environment's `ROS_DOMAIN_ID`.
    pub fn domain_from_env() -> Result<u16, BridgeError> {
        Self::parse_domain(std::env::var(DOMAIN_ENV).ok().as_deref())
    }
}

/// Why the bridge could not start.
#[derive(Debug, thiserror::Error)]
pub enum BridgeError {
    /// `ROS_DOMAIN_ID` is not a domain.
    #[error(
        "{DOMAIN_ENV}={0:?} is not a DDS domain: set it to a number from 0 to 232, or unset it for 0"
    )]
    Domain(String),
    /// The namespace is not a ROS 2 name.
    #[error(
        "ROS 2 namespace {0:?}: use '/name' (letters, digits, underscores; e.g. /robot1), or nothing"
    )]
    Namespace(String),
    /// DDS refused.
    #[error(
        "ROS 2 bridge: {0} (is another program holding the DDS ports? try another ROS_DOMAIN_ID)"
    )]
    Dds(String),
    /// This `ratf` has no DDS.
    #[error(
        "this ratf was built without ROS 2: build it with `cargo build --release -p ratf-host --features ros2`"
    )]
    NotBuilt,
}

/// The live bridge for a run of `config` when `options` asks for one: ROS commands go to
/// `operator`. Without cargo feature `ros2`, asking for one is [`BridgeError::NotBuilt`].
pub fn live_bridge(
    config: &Config,
    options: Option<&BridgeOptions>,
    operator: OperatorSender,
) -> Result<Option<Box<dyn Tap>>, BridgeError> {
    let Some(options) = options else {
        return Ok(None);
    };
    #[cfg(feature = "ros2")]
    {
        let bridge = super::bridge::Bridge::start(config, options, operator)?;
        Ok(Some(Box::new(bridge)))
    }
    #[cfg(not(feature = "ros2"))]
    {
        let _ = (config, options, operator);
        Err(BridgeError::NotBuilt)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_domain_comes_from_ros_domain_id_and_a_bad_one_is_named() {
        assert_eq!(BridgeOptions::parse_domain(None).unwrap(), 0);
        assert_eq!(BridgeOptions::parse_domain(Some(" 42 ")).unwrap(), 42);
        let error = BridgeOptions::parse_domain(Some("abc"))
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("ROS_DOMAIN_ID") && error.contains("0 to 232"),
            "{error}"
        );
        assert!(BridgeOptions::parse_domain(Some("233")).is_err());
    }

    #[cfg(not(feature = "ros2"))]
    #[test]
    fn without_the_feature_asking_for_a_bridge_says_how_to_build_one() {
        let (sender, _receiver) = crate::devices::operator::operator_channel();
        let asked = live_bridge(&Config::default(), Some(&BridgeOptions::default()), sender);
        assert!(matches!(asked, Err(BridgeError::NotBuilt)));
    }
}
