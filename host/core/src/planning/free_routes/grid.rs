//! How much room the robot has at every point of the floor, standing one way: a grid of
//! clearances for the footprint holding a heading, or for the disc it sweeps turning.

use crate::field::geometry::{Pose2, Rect, Vec2};
use crate::planning::shortcuts::FreeSpace;

/// Side of a grid cell, m. 0.01: the tightest passage on the competition floor (the
/// incoming row with a part carried) leaves the body 35 mm, so a route through it finds
/// cells at most 5 mm off its middle.
pub const CELL_M: f64 = 0.01;

/// How the robot stands while it crosses a cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Stance {
    /// Holding this heading, rad: the footprint itself must be clear.
    Held(f64),
    /// Free to turn: the whole disc the footprint sweeps turning on the spot must be clear.
    Turning,
}

impl Stance {
    /// The heading a held stance keeps, `None` while turning (the form
    /// [`FreeSpace::segment_clearance_m`] takes).
    pub fn held_yaw_rad(self) -> Option<f64> {
        match self {
            Self::Held(yaw) => Some(yaw),
            Self::Turning => None,
        }
    }

    /// The clearance at `p` standing this way in `space`, m, at most `cap_m`.
    pub fn clearance_m(self, space: &FreeSpace, p: Vec2, cap_m: f64) -> f64 {
        match self {
            Self::Held(yaw) => space.pose_clearance_m(Pose2::new(p.x, p.y, yaw), cap_m),
            Self::Turning => space.turn_clearance_m(p, cap_m),
        }
    }
}

/// The clearance of one stance at the centre of every cell of an area, m (0 where the
/// robot would touch something).
#[derive(Clone, Debug)]
pub struct ClearanceGrid {
    stance: Stance,
    area: Rect,
    columns: usize,
    rows: usize,
    clearance_m: Vec<f32>,
}

impl ClearanceGrid {
    /// The grid of `stance` in `space` over `area` (cells of [`CELL_M`] from its lower-left
    /// corner), clearances capped at `cap_m`.
    pub fn new(space: &FreeSpace, area: Rect, stance: Stance, cap_m: f64) -> Self {
        let columns = ((area.size_x() / CELL_M).floor() as usize).max(1);
        let rows = ((area.size_y() / CELL_M).floor() as usize).max(1);
        let mut grid = Self {
            stance,
            area,
            columns,
            rows,
            clearance_m: Vec::with_capacity(columns * rows),
        };
        for cell in 0..columns * rows {
            let c = stance.clearance_m(space, grid.centre(cell), cap_m);
            grid.clearance_m.push(c as f32);
        }
        grid
    }

    /// The stance it measures.
    pub fn stance(&self) -> Stance {
        self.stance
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.clearance_m.len()
    }

    /// Whether it has no cells (never: an area has at least one).
    pub fn is_empty(&self) -> bool {
        self.clearance_m.is_empty()
    }

    /// The centre of cell `cell`, m.
    pub fn centre(&self, cell: usize) -> Vec2 {
        let (column, row) = (cell % self.columns, cell / self.columns);
        Vec2::new(
            self.area.min.x + (column as f64 + 0.5) * CELL_M,
            self.area.min.y + (row as f64 + 0.5) * CELL_M,
        )
    }

    /// The cell holding `p`, `None` outside the area.
    pub fn cell_at(&self, p: Vec2) -> Option<usize> {
        let column = ((p.x - self.area.min.x) / CELL_M).floor();
        let row = ((p.y - self.area.min.y) / CELL_M).floor();
        let inside = column >= 0.0
            && row >= 0.0
            && (column as usize) < self.columns
            && (row as usize) < self.rows;
        inside.then(|| row as usize * self.columns + column as usize)
    }

    /// The clearance at the centre of cell `cell`, m (0: the robot touches something).
    pub fn clearance_m(&self, cell: usize) -> f64 {
        f64::from(self.clearance_m[cell])
    }

    /// The cells around `cell` one step away (sideways or diagonally), with the step's
    /// length in cells (1 or √2).
    pub fn neighbours(&self, cell: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let (column, row) = (
            (cell % self.columns) as isize,
            (cell / self.columns) as isize,
        );
        const STEPS: [(isize, isize, f64); 8] = [
            (1, 0, 1.0),
            (-1, 0, 1.0),
            (0, 1, 1.0),
            (0, -1, 1.0),
            (1, 1, std::f64::consts::SQRT_2),
            (1, -1, std::f64::consts::SQRT_2),
            (-1, 1, std::f64::consts::SQRT_2),
            (-1, -1, std::f64::consts::SQRT_2),
        ];
        STEPS.iter().filter_map(move |&(dx, dy, length)| {
            let (c, r) = (column + dx, row + dy);
            let inside =
                c >= 0 && r >= 0 && (c as usize) < self.columns && (r as usize) < self.rows;
            inside.then(|| (r as usize * self.columns + c as usize, length))
        })
    }

    /// The cells within `radius` cells of `p` (a square), for joining an exact point to
    /// the grid.
    pub fn cells_near(&self, p: Vec2, radius: usize) -> Vec<usize> {
        let Some(centre) = self.cell_at(p) else {
            return Vec::new();
        };
        let (column, row) = (centre % self.columns, centre / self.columns);
        let columns = column.saturating_sub(radius)..=(column + radius).min(self.columns - 1);
        let rows = row.saturating_sub(radius)..=(row + radius).min(self.rows - 1);
        rows.flat_map(|r| columns.clone().map(move |c| r * self.columns + c))
            .collect()
    }

    /// The least clearance of the cells a straight line from `a` to `b` passes (sampled
    /// every half cell), m; 0 when it leaves the area.
    pub fn line_clearance_m(&self, a: Vec2, b: Vec2) -> f64 {
        let steps = (a.distance(b) / (CELL_M / 2.0)).ceil().max(1.0) as usize;
        let mut least = f64::INFINITY;
        for k in 0..=steps {
            match self.cell_at(a + (b - a) * (k as f64 / steps as f64)) {
                Some(cell) => least = least.min(self.clearance_m(cell)),
                None => return 0.0,
            }
            if least <= 0.0 {
                break;
            }
        }
        least
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::Field;
    use crate::planning::shortcuts::Footprint;

    fn space() -> FreeSpace {
        FreeSpace::new(
            &Field::competition(),
            &[],
            Footprint::centred(0.30, 0.30, false),
            0.02,
        )
    }

    #[test]
    fn cells_map_to_their_centres_and_back() {
        let area = Rect::from_spans(-0.1, 0.1, -0.05, 0.05);
        let grid = ClearanceGrid::new(&space(), area, Stance::Turning, 0.02);
        assert_eq!(grid.len(), 20 * 10);
        for cell in 0..grid.len() {
            assert_eq!(grid.cell_at(grid.centre(cell)), Some(cell));
        }
        assert_eq!(grid.cell_at(Vec2::new(0.2, 0.0)), None);
        assert_eq!(grid.neighbours(0).count(), 3);
        assert_eq!(grid.neighbours(25).count(), 8);
        assert_eq!(grid.cells_near(grid.centre(0), 2).len(), 9);
    }

    #[test]
    fn the_clearance_is_the_gap_to_the_nearest_obstacle_up_to_the_cap() {
        let space = space();
        // Machine B's input face at x = 0.2675: a square robot facing +x at x = 0.1 has
        // 17.5 mm; turning there, its disc (0.212 m) overlaps.
        // One cell, centred on (0.1, 0.15).
        let area = Rect::from_spans(0.095, 0.105, 0.145, 0.155);
        let held = ClearanceGrid::new(&space, area, Stance::Held(0.0), 0.05);
        assert_eq!(held.len(), 1);
        assert!(
            (held.clearance_m(0) - 0.0175).abs() < 1e-6,
            "{}",
            held.clearance_m(0)
        );
        let turning = ClearanceGrid::new(&space, area, Stance::Turning, 0.05);
        assert_eq!(turning.clearance_m(0), 0.0);
        // In the middle of the floor the cap stands.
        let open = Rect::from_spans(-0.01, 0.01, -0.01, 0.01);
        let grid = ClearanceGrid::new(&space, open, Stance::Held(0.3), 0.02);
        assert!((grid.clearance_m(0) - 0.02).abs() < 1e-6);
    }
}
