//! Which wheel turned, which way: verdicts from encoder counts (pure).
//!
//! Conventions (host/core/src/kinematics.rs, hardware/pinmap.md): motor `k` is on the motor
//! shield's port M(k+1) and its encoder on the Mega's pins 22 + 2k (A) and 23 + 2k (B). A
//! positive PWM or speed must give positive ticks on the same wheel (the Mega's PI relies
//! on it) and turns the wheel clockwise seen from outside the robot: the right wheels
//! (0, 2) roll forward, the left wheels (1, 3) backward (`[robot] wheel_forward_sign`).

use serde::Serialize;

/// The wheels' names, motor index order.
pub const WHEEL_NAMES: [&str; 4] = ["back-right", "back-left", "front-right", "front-left"];

/// How a wheel was made to turn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Drive {
    /// Open-loop PWM of this sign on its motor; `seen_clockwise`: whether the person
    /// watching saw the wheel turn clockwise from outside the robot (`None`: nobody said).
    OpenLoop {
        /// +1 or −1.
        pwm_sign: i8,
        /// What the person saw.
        seen_clockwise: Option<bool>,
    },
    /// Turned by hand so that its rim rolls forward; `forward_sign` is the tick sign that
    /// gives (`[robot] wheel_forward_sign`).
    ByHand {
        /// +1 or −1.
        forward_sign: i8,
    },
}

/// What the counts say about one wheel.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(tag = "verdict", rename_all = "snake_case")]
pub enum WheelVerdict {
    /// The wheel turned the expected way, alone or with others dragged along much less.
    Ok {
        /// Its ticks.
        ticks: i64,
        /// Other wheels that turned a little (the robot on the floor drags them).
        dragged: Vec<usize>,
    },
    /// It turned the wrong way (ticks of the wrong sign).
    WrongWay {
        /// Its ticks.
        ticks: i64,
    },
    /// Ticks of the right sign, but the person saw it turn the wrong way: both the motor's
    /// wires and the encoder's A/B are swapped.
    Mirrored {
        /// Its ticks.
        ticks: i64,
    },
    /// Another wheel turned and this one did not.
    WrongWheel {
        /// The wheels that turned, with their ticks.
        moved: Vec<(usize, i64)>,
    },
    /// This wheel turned, and another turned about as much.
    AlsoMoved {
        /// Its ticks.
        ticks: i64,
        /// The others, with their ticks.
        others: Vec<(usize, i64)>,
    },
    /// No wheel turned.
    NoMotion,
}

impl WheelVerdict {
    /// True when nothing is wrong.
    pub fn is_ok(&self) -> bool {
        matches!(self, Self::Ok { .. })
    }
}

/// The verdict for wheel `wheel` driven by `drive`, from the ticks every wheel counted
/// meanwhile; a wheel "turned" when it counted at least `moved_ticks`, and another wheel
/// is only dragged along when it turned less than half as much as this one.
pub fn judge(wheel: usize, drive: Drive, ticks: [i64; 4], moved_ticks: i64) -> WheelVerdict {
    let own = ticks.get(wheel).copied().unwrap_or(0);
    let others: Vec<(usize, i64)> = (0..4)
        .filter(|&k| k != wheel && ticks[k].abs() >= moved_ticks.max(1))
        .map(|k| (k, ticks[k]))
        .collect();
    if own.abs() < moved_ticks.max(1) {
        return if others.is_empty() {
            WheelVerdict::NoMotion
        } else {
            WheelVerdict::WrongWheel { moved: others }
        };
    }
    let (rivals, dragged): (Vec<_>, Vec<_>) = others
        .into_iter()
        .partition(|&(_, t)| 2 * t.abs() >= own.abs());
    if !rivals.is_empty() {
        return WheelVerdict::AlsoMoved {
            ticks: own,
            others: rivals,
        };
    }
    let expected_sign = match drive {
        Drive::OpenLoop { pwm_sign, .. } => pwm_sign,
        Drive::ByHand { forward_sign } => forward_sign,
    };
    let right_sign = own.signum() == i64::from(expected_sign.signum());
    // The person's view: clockwise is what the command asks for when its sign is +.
    let seen_right = match drive {
        Drive::OpenLoop {
            pwm_sign,
            seen_clockwise: Some(cw),
        } => Some(cw == (pwm_sign > 0)),
        _ => None,
    };
    match (right_sign, seen_right) {
        (true, Some(false)) => WheelVerdict::Mirrored { ticks: own },
        (true, _) => WheelVerdict::Ok {
            ticks: own,
            dragged: dragged.into_iter().map(|(k, _)| k).collect(),
        },
        (false, _) => WheelVerdict::WrongWay { ticks: own },
    }
}

fn encoder_pins(wheel: usize) -> String {
    format!("pins {} (A) and {} (B)", 22 + 2 * wheel, 23 + 2 * wheel)
}

fn name(wheel: usize) -> &'static str {
    WHEEL_NAMES.get(wheel).copied().unwrap_or("unknown")
}

fn list(moved: &[(usize, i64)]) -> String {
    moved
        .iter()
        .map(|&(k, t)| format!("wheel {k} ({}) {t:+} ticks", name(k)))
        .collect::<Vec<_>>()
        .join(", ")
}

/// One line saying what was seen and, when wrong, what to check (hardware/pinmap.md).
pub fn describe(wheel: usize, drive: Drive, verdict: &WheelVerdict) -> String {
    let port = format!("shield port M{}", wheel + 1);
    let pins = encoder_pins(wheel);
    let by_hand = matches!(drive, Drive::ByHand { .. });
    let seen = matches!(
        drive,
        Drive::OpenLoop {
            seen_clockwise: Some(_),
            ..
        }
    );
    match verdict {
        WheelVerdict::Ok { ticks, dragged } if dragged.is_empty() => {
            format!("turned the right way, {ticks:+} ticks")
        }
        WheelVerdict::Ok { ticks, dragged } => format!(
            "turned the right way, {ticks:+} ticks (wheel(s) {dragged:?} turned less: dragged \
             along, is the robot on the floor?)"
        ),
        WheelVerdict::WrongWay { ticks } if by_hand => format!(
            "counted {ticks:+} ticks rolling forward, the wrong sign: encoder {wheel}'s A and B \
             are swapped (swap the wires on {pins}), or the wheel was turned the other way"
        ),
        WheelVerdict::WrongWay { ticks } if seen => format!(
            "counted {ticks:+} ticks, the wrong sign, and turned the way the command asks: \
             encoder {wheel}'s A and B are swapped (swap the wires on {pins})"
        ),
        WheelVerdict::WrongWay { ticks } => format!(
            "counted {ticks:+} ticks, the wrong sign for a positive PWM: motor {wheel}'s wires \
             are swapped on {port}, or encoder {wheel}'s A and B on {pins} (if the wheel turned \
             clockwise seen from outside, it is the encoder; run interactively to be asked)"
        ),
        WheelVerdict::Mirrored { ticks } => format!(
            "counted {ticks:+} ticks, the right sign, but turned the wrong way: both motor \
             {wheel}'s wires on {port} and encoder {wheel}'s A/B on {pins} are swapped (swap \
             both, or flip [robot] wheel_forward_sign[{wheel}])"
        ),
        WheelVerdict::WrongWheel { moved } if by_hand => format!(
            "nothing on encoder {wheel}, but {}: the encoder cables are crossed (encoder {wheel} \
             belongs on {pins})",
            list(moved)
        ),
        WheelVerdict::WrongWheel { moved } => format!(
            "did not turn, but {} did: motor {wheel} is on the wrong motor channel (it belongs \
             on {port}) or the encoder cables are crossed (encoder {wheel} belongs on {pins})",
            list(moved)
        ),
        WheelVerdict::AlsoMoved { ticks, others } => format!(
            "turned ({ticks:+} ticks) and so did {}: two motors on one channel, or encoder \
             cables crossed (encoder {wheel} belongs on {pins}, motor {wheel} on {port})",
            list(others)
        ),
        WheelVerdict::NoMotion if by_hand => format!(
            "no encoder counted: check encoder {wheel}'s wires on {pins}, its 5 V and ground"
        ),
        WheelVerdict::NoMotion => format!(
            "no encoder counted: check the motors' power (battery, the shield's power input), \
             motor {wheel}'s wires on {port}, encoder {wheel} on {pins}; the Mega's I2C fault \
             count tells whether the shield answers"
        ),
    }
}

/// Fewest ticks that count as turning: 1/50 of a wheel revolution (7.2°), far above
/// vibration and far below a hand's quarter turn or one second at 20 % PWM.
pub fn moved_ticks(ticks_per_wheel_rev: f64) -> i64 {
    (ticks_per_wheel_rev / 50.0).round().max(1.0) as i64
}

#[cfg(test)]
mod tests {
    use super::*;

    const OPEN: Drive = Drive::OpenLoop {
        pwm_sign: 1,
        seen_clockwise: None,
    };

    #[test]
    fn the_commanded_wheel_alone_the_right_way_is_ok() {
        let verdict = judge(2, OPEN, [0, 3, 900, -2], 56);
        assert_eq!(
            verdict,
            WheelVerdict::Ok {
                ticks: 900,
                dragged: vec![]
            }
        );
        assert!(describe(2, OPEN, &verdict).starts_with("turned the right way, +900"));
    }

    #[test]
    fn a_wheel_that_turned_backwards_names_the_motor_wires_and_the_encoder() {
        let verdict = judge(1, OPEN, [0, -850, 0, 0], 56);
        assert_eq!(verdict, WheelVerdict::WrongWay { ticks: -850 });
        let text = describe(1, OPEN, &verdict);
        assert!(text.contains("shield port M2"), "{text}");
        assert!(text.contains("pins 24 (A) and 25 (B)"), "{text}");
        // Seen turning as commanded: the encoder alone.
        let seen = Drive::OpenLoop {
            pwm_sign: 1,
            seen_clockwise: Some(true),
        };
        let text = describe(1, seen, &judge(1, seen, [0, -850, 0, 0], 56));
        assert!(text.contains("encoder 1's A and B are swapped"), "{text}");
        assert!(!text.contains("M2"), "{text}");
    }

    #[test]
    fn right_ticks_but_seen_turning_the_wrong_way_is_mirrored() {
        let seen = Drive::OpenLoop {
            pwm_sign: 1,
            seen_clockwise: Some(false),
        };
        let verdict = judge(0, seen, [700, 0, 0, 0], 56);
        assert_eq!(verdict, WheelVerdict::Mirrored { ticks: 700 });
        assert!(describe(0, seen, &verdict).contains("wheel_forward_sign[0]"));
    }

    #[test]
    fn the_wrong_wheel_is_named_with_the_channel_and_the_encoder_cables() {
        let verdict = judge(0, OPEN, [4, 0, 880, 0], 56);
        assert_eq!(
            verdict,
            WheelVerdict::WrongWheel {
                moved: vec![(2, 880)]
            }
        );
        let text = describe(0, OPEN, &verdict);
        assert!(text.contains("wheel 2 (front-right) +880 ticks"), "{text}");
        assert!(text.contains("wrong motor channel"), "{text}");
        assert!(text.contains("shield port M1"), "{text}");
    }

    #[test]
    fn no_wheel_turning_is_no_motion() {
        let verdict = judge(3, OPEN, [1, -2, 0, 40], 56);
        assert_eq!(verdict, WheelVerdict::NoMotion);
        assert!(describe(3, OPEN, &verdict).contains("motor 3's wires on shield port M4"));
        let hand = Drive::ByHand { forward_sign: -1 };
        assert!(describe(3, hand, &verdict).contains("encoder 3's wires on pins 28 (A)"));
    }

    #[test]
    fn wheels_dragged_along_are_tolerated_but_a_rival_is_not() {
        assert_eq!(
            judge(0, OPEN, [1000, 300, -120, 10], 56),
            WheelVerdict::Ok {
                ticks: 1000,
                dragged: vec![1, 2]
            }
        );
        assert_eq!(
            judge(0, OPEN, [1000, 0, 600, 0], 56),
            WheelVerdict::AlsoMoved {
                ticks: 1000,
                others: vec![(2, 600)]
            }
        );
    }

    #[test]
    fn by_hand_the_forward_sign_decides() {
        let left = Drive::ByHand { forward_sign: -1 };
        assert!(judge(1, left, [0, -400, 0, 0], 56).is_ok());
        let verdict = judge(1, left, [0, 400, 0, 0], 56);
        assert_eq!(verdict, WheelVerdict::WrongWay { ticks: 400 });
        assert!(describe(1, left, &verdict).contains("encoder 1's A and B are swapped"));
        let verdict = judge(1, left, [0, 0, 0, -400], 56);
        assert!(describe(1, left, &verdict).contains("encoder cables are crossed"));
    }

    #[test]
    fn a_fiftieth_of_a_revolution_counts_as_turning() {
        assert_eq!(moved_ticks(2803.2), 56);
        assert_eq!(moved_ticks(0.0), 1);
    }
}
