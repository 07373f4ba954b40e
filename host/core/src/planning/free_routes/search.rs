//! The cheapest way across layered clearance grids: the robot holds its start heading
//! (layer 0), may turn where the disc it sweeps is clear (layer 1), and holds a goal
//! heading after (layers 2 and on, one per goal heading). Dijkstra over (layer, cell), each
//! step costing its length weighted by how little room the cells leave, the turning layer's
//! steps discounted so that the search prefers to cross open floor where the robot turns.

use std::collections::BinaryHeap;

use super::grid::{CELL_M, ClearanceGrid};
use crate::planning::cheapest_first::Cheapest;

/// What a step costs (module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepCosts {
    /// The clearance beyond which room costs nothing more, m (the navigation's margin).
    pub cap_m: f64,
    /// How much dearer a metre is with no room at all than with the cap's: a metre with
    /// clearance `c` costs `1 + clearance_weight · (1 − c / cap)²`.
    pub clearance_weight: f64,
    /// The factor on a metre driven in the turning layer (≤ 1: the turn is cheaper to
    /// spread over open floor).
    pub turn_discount: f64,
    /// The least clearance the robot turns with, m: a turning cell with less is blocked.
    /// The whole margin: while it turns the follower holds its heading least well.
    pub turn_floor_m: f64,
}

impl StepCosts {
    /// The weight of a metre at clearance `clearance_m`.
    pub fn weight(&self, clearance_m: f64) -> f64 {
        let short = (1.0 - clearance_m / self.cap_m).clamp(0.0, 1.0);
        1.0 + self.clearance_weight * short * short
    }
}

/// A cell of a layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct State {
    /// 0: the start heading; 1: turning; 2 and on: the goal headings.
    pub layer: usize,
    /// The cell.
    pub cell: usize,
}

/// The layers of one search.
#[derive(Clone, Copy, Debug)]
pub struct Layers<'a> {
    /// The robot holding its start heading.
    pub start: &'a ClearanceGrid,
    /// The robot turning (its swept disc).
    pub turning: &'a ClearanceGrid,
    /// The robot holding each goal heading that differs from the start's.
    pub goals: &'a [&'a ClearanceGrid],
}

impl Layers<'_> {
    fn count(&self) -> usize {
        2 + self.goals.len()
    }

    fn grid(&self, layer: usize) -> &ClearanceGrid {
        match layer {
            0 => self.start,
            1 => self.turning,
            goal => self.goals[goal - 2],
        }
    }
}

/// The cheapest costs from the sources to every state, and the way back.
#[derive(Clone, Debug)]
pub struct Tree {
    cells: usize,
    cost: Vec<f64>,
    previous: Vec<u32>,
}

/// No previous state: a source, or not reached.
const NONE: u32 = u32::MAX;

impl Tree {
    fn index(&self, state: State) -> usize {
        state.layer * self.cells + state.cell
    }

    /// The cheapest cost of reaching `state` (infinite if it cannot be).
    pub fn cost(&self, state: State) -> f64 {
        self.cost[self.index(state)]
    }

    /// The states from a source to `state`, in order (empty if it cannot be reached).
    pub fn path_to(&self, state: State) -> Vec<State> {
        if !self.cost(state).is_finite() {
            return Vec::new();
        }
        let mut path = vec![state];
        let mut at = self.index(state);
        while self.previous[at] != NONE {
            at = self.previous[at] as usize;
            path.push(State {
                layer: at / self.cells,
                cell: at % self.cells,
            });
        }
        path.reverse();
        path
    }
}

/// Dijkstra from `sources` (states with their costs) over `layers`: steps to the eight
/// neighbouring cells within a layer where the next cell has room (turning, at least
/// [`StepCosts::turn_floor_m`]), and from the start layer into the turning one, and from
/// the turning layer into each goal layer, at no cost, in any cell where the robot can
/// turn. Every layer's grid covers the same cells.
pub fn cheapest(layers: &Layers<'_>, costs: &StepCosts, sources: &[(State, f64)]) -> Tree {
    let cells = layers.start.len();
    let count = layers.count();
    let mut tree = Tree {
        cells,
        cost: vec![f64::INFINITY; cells * count],
        previous: vec![NONE; cells * count],
    };
    let mut queue = BinaryHeap::new();
    for &(state, cost) in sources {
        let index = tree.index(state);
        if cost < tree.cost[index] {
            tree.cost[index] = cost;
            queue.push(Cheapest { cost, item: index });
        }
    }
    let mut done = vec![false; cells * count];
    while let Some(Cheapest { cost, item: index }) = queue.pop() {
        if done[index] {
            continue;
        }
        done[index] = true;
        let (layer, cell) = (index / cells, index % cells);
        let grid = layers.grid(layer);
        let here = grid.clearance_m(cell);
        let mut relax = |next: usize, next_cost: f64| {
            if next_cost < tree.cost[next] {
                tree.cost[next] = next_cost;
                tree.previous[next] = index as u32;
                queue.push(Cheapest {
                    cost: next_cost,
                    item: next,
                });
            }
        };
        let (factor, floor) = if layer == 1 {
            (costs.turn_discount, costs.turn_floor_m)
        } else {
            (1.0, 0.0)
        };
        for (next, cells_apart) in grid.neighbours(cell) {
            let there = grid.clearance_m(next);
            if there <= floor || there <= 0.0 {
                continue;
            }
            let weight = (costs.weight(here) + costs.weight(there)) / 2.0;
            relax(
                layer * cells + next,
                cost + cells_apart * CELL_M * weight * factor,
            );
        }
        let room = layers.turning.clearance_m(cell);
        let can_turn = room > 0.0 && room >= costs.turn_floor_m;
        if can_turn {
            match layer {
                0 => relax(cells + cell, cost),
                1 => {
                    for goal in 2..count {
                        relax(goal * cells + cell, cost);
                    }
                }
                _ => {}
            }
        }
    }
    tree
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::geometry::{Rect, Vec2};
    use crate::planning::free_routes::grid::Stance;
    use crate::planning::shortcuts::{Footprint, FreeSpace};

    const COSTS: StepCosts = StepCosts {
        cap_m: 0.02,
        clearance_weight: 2.0,
        turn_discount: 1.0,
        turn_floor_m: 0.0,
    };

    /// A floor with one wall, the robot a 10 cm square (its disc 71 mm).
    fn space(walls: Vec<Rect>) -> FreeSpace {
        FreeSpace::with_walls(walls, Footprint::centred(0.10, 0.10, false), 0.0)
    }

    /// The three layers of `walls` over `area` (the 10 cm square holding 0 rad, turning,
    /// holding `goal_yaw`, margin 2 cm).
    struct Floor {
        held: ClearanceGrid,
        turning: ClearanceGrid,
        goal: ClearanceGrid,
    }

    impl Floor {
        fn new(walls: Vec<Rect>, area: Rect, goal_yaw: f64) -> Self {
            let space = space(walls);
            Self {
                held: ClearanceGrid::new(&space, area, Stance::Held(0.0), 0.02),
                turning: ClearanceGrid::new(&space, area, Stance::Turning, 0.02),
                goal: ClearanceGrid::new(&space, area, Stance::Held(goal_yaw), 0.02),
            }
        }

        /// The search's tree from the held layer's cell at `from`, and that cell.
        fn search_from(&self, from: Vec2) -> (Tree, usize) {
            let goals = [&self.goal];
            let layers = Layers {
                start: &self.held,
                turning: &self.turning,
                goals: &goals,
            };
            let cell = self.held.cell_at(from).unwrap();
            let source = State { layer: 0, cell };
            (cheapest(&layers, &COSTS, &[(source, 0.0)]), cell)
        }
    }

    #[test]
    fn the_weight_grows_as_the_room_shrinks() {
        assert_eq!(COSTS.weight(0.02), 1.0);
        assert_eq!(COSTS.weight(0.05), 1.0);
        assert_eq!(COSTS.weight(0.0), 3.0);
        assert!((COSTS.weight(0.01) - 1.5).abs() < 1e-12);
    }

    #[test]
    fn an_open_floor_costs_the_straight_steps_and_the_turn_is_free_to_enter() {
        let floor = Floor::new(Vec::new(), Rect::from_spans(0.0, 0.3, 0.0, 0.2), 1.0);
        let (tree, from) = floor.search_from(Vec2::new(0.005, 0.005));
        let to = floor.held.cell_at(Vec2::new(0.105, 0.055)).unwrap();
        // 10 cells across and 5 up: 5 diagonal steps and 5 straight ones.
        let expected = (5.0 * std::f64::consts::SQRT_2 + 5.0) * CELL_M;
        for layer in 0..3 {
            let cost = tree.cost(State { layer, cell: to });
            assert!((cost - expected).abs() < 1e-9, "layer {layer}: {cost}");
        }
        let path = tree.path_to(State { layer: 2, cell: to });
        assert_eq!(
            path.first(),
            Some(&State {
                layer: 0,
                cell: from
            })
        );
        assert!(path.iter().any(|s| s.layer == 1));
        assert!(path.windows(2).all(|w| w[0].layer <= w[1].layer));
    }

    #[test]
    fn a_wall_is_gone_round_and_the_turn_waits_for_room() {
        // A wall across the middle and one along the top leave a gap the 10 cm square fits
        // through holding its heading but cannot turn in (12 cm: its disc needs 14.2 cm).
        let wall = Rect::from_spans(0.19, 0.21, 0.0, 0.28);
        let top = Rect::from_spans(0.0, 0.4, 0.40, 0.42);
        let floor = Floor::new(vec![wall, top], Rect::from_spans(0.0, 0.4, 0.0, 0.4), 0.5);
        let (tree, _) = floor.search_from(Vec2::new(0.085, 0.085));
        let (held, turning) = (&floor.held, &floor.turning);
        let to = held.cell_at(Vec2::new(0.315, 0.085)).unwrap();
        let path = tree.path_to(State { layer: 0, cell: to });
        assert!(!path.is_empty());
        // Over the top of the wall, never through it.
        let highest = path
            .iter()
            .map(|s| held.centre(s.cell).y)
            .fold(f64::MIN, f64::max);
        assert!(highest > 0.28 + 0.05 && highest < 0.40 - 0.05, "{highest}");
        for s in &path {
            assert!(held.clearance_m(s.cell) > 0.0);
        }
        // Turning to the goal heading, the robot never turns in the gap over the wall.
        let turned = tree.path_to(State { layer: 2, cell: to });
        assert!(turned.iter().any(|s| s.layer == 1));
        for s in turned.iter().filter(|s| s.layer == 1) {
            assert!(turning.clearance_m(s.cell) > 0.0);
            let x = turning.centre(s.cell).x;
            assert!(!(0.19..0.21).contains(&x), "turning at {x}");
        }
    }
}
