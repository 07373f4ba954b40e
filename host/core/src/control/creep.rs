//! The creep to contact that ends a docking approach to a part: straight on from where the
//! approach ended until the box switch closes, or a bounded distance further on. The
//! approach reaches the pick pose moving at the creep speed (`control::follower`), so a part
//! standing deeper in its slot than its nominal place, or a pose estimate a little short, is
//! met without a stop.

use crate::config::NavigationConfig;
use crate::control::follower::Status;
use crate::field::geometry::Pose2;
use crate::kinematics::BodyTwist;

/// How a creep goes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CreepLimits {
    /// Speed straight ahead, m/s.
    pub speed_m_s: f64,
    /// Farthest it goes, m (0: no creep).
    pub limit_m: f64,
}

impl CreepLimits {
    /// Our robot's: `[navigation]`'s `dock_creep_speed_m_s` and `dock_creep_m`.
    pub fn ours(config: &NavigationConfig) -> Self {
        Self {
            speed_m_s: config.dock_creep_speed_m_s,
            limit_m: config.dock_creep_m,
        }
    }
}

/// A creep under way.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Creep {
    from: Pose2,
    limits: CreepLimits,
}

impl Creep {
    /// Creep straight ahead from `from` (the pose estimate where the approach ended) under
    /// `limits`.
    pub fn new(from: Pose2, limits: CreepLimits) -> Self {
        Self { from, limits }
    }

    /// One tick with the pose estimate and the switch: the twist to command and where the
    /// creep is (`Docked` on the switch, `Arrived` once `limit_m` is behind it without the
    /// switch, else `Following`).
    pub fn update(&self, pose: Pose2, switch_pressed: bool) -> (BodyTwist, Status) {
        if switch_pressed {
            (BodyTwist::default(), Status::Docked)
        } else if self.from.position().distance(pose.position()) > self.limits.limit_m {
            (BodyTwist::default(), Status::Arrived)
        } else {
            (
                BodyTwist::new(self.limits.speed_m_s, 0.0, 0.0),
                Status::Following,
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_creep_goes_on_until_the_switch_or_its_limit() {
        let limits = CreepLimits {
            speed_m_s: 0.05,
            limit_m: 0.04,
        };
        let creep = Creep::new(Pose2::new(1.0, 0.0, 0.0), limits);
        let at = |x: f64, switch| creep.update(Pose2::new(x, 0.0, 0.0), switch);
        assert_eq!(
            at(1.01, false),
            (BodyTwist::new(0.05, 0.0, 0.0), Status::Following)
        );
        assert_eq!(at(1.01, true), (BodyTwist::default(), Status::Docked));
        assert_eq!(at(1.05, false), (BodyTwist::default(), Status::Arrived));
    }
}
