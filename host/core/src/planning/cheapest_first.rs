//! The queue entry of every Dijkstra search in planning: [`Cheapest`] orders
//! `std::collections::BinaryHeap` (a max-heap) so that it pops the least cost first and,
//! among equal costs, the least item, a tie-break that makes a search's result depend only on
//! its input (never on the order things were pushed in).

use std::cmp::Ordering;

/// An item queued at the cost of reaching it (metres, seconds, or any other additive cost).
#[derive(Clone, Copy, Debug)]
pub struct Cheapest<T> {
    /// The cost of reaching `item`.
    pub cost: f64,
    /// What is queued: a vertex, a grid cell, a search state.
    pub item: T,
}

impl<T: Ord> Ord for Cheapest<T> {
    fn cmp(&self, other: &Self) -> Ordering {
        other
            .cost
            .total_cmp(&self.cost)
            .then_with(|| other.item.cmp(&self.item))
    }
}

impl<T: Ord> PartialOrd for Cheapest<T> {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl<T: Ord> PartialEq for Cheapest<T> {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other).is_eq()
    }
}

impl<T: Ord> Eq for Cheapest<T> {}

#[cfg(test)]
mod tests {
    use std::collections::BinaryHeap;

    use super::*;

    #[test]
    fn the_heap_pops_the_least_cost_first_and_the_least_item_among_equal_costs() {
        let mut queue: BinaryHeap<_> = [(2.0, 'a'), (0.5, 'z'), (1.0, 'c'), (1.0, 'b'), (3.0, 'd')]
            .into_iter()
            .map(|(cost, item)| Cheapest { cost, item })
            .collect();
        let mut popped = Vec::new();
        while let Some(Cheapest { cost, item }) = queue.pop() {
            popped.push((cost, item));
        }
        assert_eq!(
            popped,
            [(0.5, 'z'), (1.0, 'b'), (1.0, 'c'), (2.0, 'a'), (3.0, 'd')]
        );
    }
}
