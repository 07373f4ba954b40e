//! The order of the competition's actions: which part to move next, to which machine (type
//! and row) or outgoing slot, minimising the estimated time until every part is finished
//! (full score: every part blue in the outgoing warehouse having visited its machines).
//!
//! [`travel`] holds the places and the travel times (supplied by the caller through
//! [`TravelTimes`]); [`model`] is the rest of the world (handling and machine times, the
//! parts' state and what an action does); a [`Policy`] turns a [`State`] into a [`Plan`].
//! Two policies: [`BranchAndBound`] ("ours", optimal over every sequence) and [`Original`]
//! (the 5dpo priority rules). Both are re-run after every action from the known state,
//! corrected by the server's strings when it answers: [`State::from_server`] reads them and
//! [`State::reconcile`] takes them as the truth about where the parts are while keeping what
//! only the robot knows (machine ready times); `competition::TaskActions` does this
//! (competition.md §6).

pub mod model;
pub mod original;
pub mod search;
pub mod travel;

pub use model::{
    Action, MAX_PARTS, Model, PLANNED_MAGNET_FACES, PartState, Place, Rules, State, TaskError,
    TimedAction, Timing, check_magnet_faces,
};
pub use original::Original;
pub use search::BranchAndBound;
pub use travel::{LOCATION_COUNT, Location, StraightLineTimes, TravelMatrix, TravelTimes};

/// A sequence of actions with their estimated times.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    /// The actions in order, each with its estimated pick and finish time.
    pub steps: Vec<TimedAction>,
    /// When the last action finishes (the state's time if nothing is left), s.
    pub finish_s: f64,
    /// Whether the plan is proven the fastest (branch and bound run to the end).
    pub optimal: bool,
    /// States the policy expanded (the search effort).
    pub nodes: u64,
}

impl Plan {
    /// The first action, the one to do now (`None` when everything is finished).
    pub fn next(&self) -> Option<Action> {
        self.steps.first().map(|s| s.action)
    }
}

/// A way of choosing actions.
pub trait Policy {
    /// A short name ("ours", "original").
    fn name(&self) -> &'static str;

    /// The plan from `state` to full score.
    fn plan(&self, model: &Model, state: &State) -> Result<Plan, TaskError>;
}

/// The policy chosen by name on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PolicyKind {
    /// [`BranchAndBound`].
    Ours,
    /// [`Original`] with the deployed `mach_b = true`.
    Original,
}

impl PolicyKind {
    /// The policy itself.
    pub fn policy(self) -> Box<dyn Policy + Send + Sync> {
        match self {
            Self::Ours => Box::new(BranchAndBound::default()),
            Self::Original => Box::new(Original::default()),
        }
    }
}

impl std::str::FromStr for PolicyKind {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "ours" => Ok(Self::Ours),
            "original" => Ok(Self::Original),
            other => Err(format!("unknown policy {other:?}: ours or original")),
        }
    }
}
