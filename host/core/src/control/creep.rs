//! The creep to contact that ends a docking approach to a part: straight on from where the
//! approach ended until the box switch closes, or a bounded distance further on. The
//! approach reaches the pick pose moving at the creep speed (`control::follower`), so a part
//! standing deeper in its slot than its nominal place, or a pose estimate a little short, is
//! met without a stop.

use crate::control::follower::Status;
use crate::field::geometry::Pose2;
use crate::kinematics::BodyTwist;

/// A creep under way.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Creep {
    from: Pose2,
    speed_m_s: f64,
    limit_m: f64,
}

impl Creep {
    /// Creep straight ahead at `speed_m_s` (m/s) from `from` (the pose estimate where the
    /// approach ended) for at most `limit_m` (m).
    pub fn new(from: Pose2, speed_m_s: f64, limit_m: f64) -> Self {
        Self {
            from,
            speed_m_s,
            limit_m,
        }
    }

    /// One tick with the pose estimate and the switch: the twist to command and where the
    /// creep is (`Docked` on the switch, `Arrived` once `limit_m` is behind it without the
    /// switch, else `Following`).
    pub fn update(&self, pose: Pose2, switch_pressed: bool) -> (BodyTwist, Status) {
        if switch_pressed {
            (BodyTwist::default(), Status::Docked)
        } else if self.from.position().distance(pose.position()) > self.limit_m {
            (BodyTwist::default(), Status::Arrived)
        } else {
            (BodyTwist::new(self.speed_m_s, 0.0, 0.0), Status::Following)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_creep_goes_on_until_the_switch_or_its_limit() {
        let creep = Creep::new(Pose2::new(1.0, 0.0, 0.0), 0.05, 0.04);
        let at = |x: f64, switch| creep.update(Pose2::new(x, 0.0, 0.0), switch);
        assert_eq!(
            at(1.01, false),
            (BodyTwist::new(0.05, 0.0, 0.0), Status::Following)
        );
        assert_eq!(at(1.01, true), (BodyTwist::default(), Status::Docked));
        assert_eq!(at(1.05, false), (BodyTwist::default(), Status::Arrived));
    }
}
