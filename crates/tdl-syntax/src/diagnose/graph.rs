//! Cycles in a small directed graph, for the static checks that look for circular waits
//! (`cycles.rs`) and unbounded recursion (`recursion.rs`): the strongly connected components
//! (Tarjan's algorithm, iterative so that no input can exhaust the stack) and one shortest cycle
//! through each component that has one.
//!
//! The graphs are tiny (a body's spawns, a program's tasks), so this is written here rather than
//! taken from a graph crate: the front end is compiled into every `tdl!` user's build.

use std::collections::VecDeque;

/// One cycle per strongly connected component that has one (several nodes, or one node with an
/// edge to itself), as the indexes into `edges` of its edges in order. Nodes are `0..nodes`;
/// edges naming other nodes are ignored. A component's cycle is a shortest one through its
/// smallest node; components come in the order of their smallest node.
pub(super) fn cycles(nodes: usize, edges: &[(usize, usize)]) -> Vec<Vec<usize>> {
    let mut out_edges: Vec<Vec<usize>> = vec![Vec::new(); nodes];
    for (i, &(from, to)) in edges.iter().enumerate() {
        if from < nodes && to < nodes {
            out_edges[from].push(i);
        }
    }
    let component = components(nodes, edges, &out_edges);
    let mut smallest: Vec<Option<usize>> = vec![None; nodes];
    let mut size = vec![0usize; nodes];
    for (node, &c) in component.iter().enumerate() {
        size[c] += 1;
        smallest[c].get_or_insert(node);
    }
    let mut starts: Vec<usize> = Vec::new();
    for (c, first) in smallest.iter().enumerate() {
        let Some(first) = *first else { continue };
        let self_loop = out_edges[first].iter().any(|&e| edges[e].1 == first);
        if size[c] > 1 || self_loop {
            starts.push(first);
        }
    }
    starts.sort_unstable();
    starts
        .into_iter()
        .filter_map(|start| shortest_cycle(start, edges, &out_edges, &component))
        .collect()
}

/// The component number of each node (Tarjan's algorithm with an explicit stack).
fn components(nodes: usize, edges: &[(usize, usize)], out_edges: &[Vec<usize>]) -> Vec<usize> {
    const UNSEEN: usize = usize::MAX;
    let mut index = vec![UNSEEN; nodes];
    let mut low = vec![0usize; nodes];
    let mut on_stack = vec![false; nodes];
    let mut stack: Vec<usize> = Vec::new();
    let mut component = vec![UNSEEN; nodes];
    let mut next_index = 0;
    let mut next_component = 0;
    // (node, how many of its out-edges were followed)
    let mut calls: Vec<(usize, usize)> = Vec::new();
    for root in 0..nodes {
        if index[root] != UNSEEN {
            continue;
        }
        calls.push((root, 0));
        index[root] = next_index;
        low[root] = next_index;
        next_index += 1;
        stack.push(root);
        on_stack[root] = true;
        while let Some(&mut (node, ref mut followed)) = calls.last_mut() {
            if let Some(&e) = out_edges[node].get(*followed) {
                *followed += 1;
                let to = edges[e].1;
                if index[to] == UNSEEN {
                    index[to] = next_index;
                    low[to] = next_index;
                    next_index += 1;
                    stack.push(to);
                    on_stack[to] = true;
                    calls.push((to, 0));
                } else if on_stack[to] {
                    low[node] = low[node].min(index[to]);
                }
                continue;
            }
            calls.pop();
            if let Some(&(caller, _)) = calls.last() {
                low[caller] = low[caller].min(low[node]);
            }
            if low[node] == index[node] {
                while let Some(member) = stack.pop() {
                    on_stack[member] = false;
                    component[member] = next_component;
                    if member == node {
                        break;
                    }
                }
                next_component += 1;
            }
        }
    }
    component
}

/// A shortest cycle from `start` back to it within its component (breadth first), as edge
/// indexes in order.
fn shortest_cycle(
    start: usize,
    edges: &[(usize, usize)],
    out_edges: &[Vec<usize>],
    component: &[usize],
) -> Option<Vec<usize>> {
    let mut reached_by: Vec<Option<usize>> = vec![None; out_edges.len()];
    let mut queue = VecDeque::from([start]);
    while let Some(node) = queue.pop_front() {
        for &e in &out_edges[node] {
            let to = edges[e].1;
            if component[to] != component[start] {
                continue;
            }
            if to == start {
                let mut path = vec![e];
                let mut at = node;
                while at != start {
                    let back = reached_by[at]?;
                    path.push(back);
                    at = edges[back].0;
                }
                path.reverse();
                return Some(path);
            }
            if reached_by[to].is_none() {
                reached_by[to] = Some(e);
                queue.push_back(to);
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::cycles;

    #[test]
    fn finds_one_shortest_cycle_per_component() {
        // 0 -> 1 -> 2 -> 0 and the shortcut 1 -> 0; 3 -> 3; 4 -> 5 (no cycle).
        let edges = [(0, 1), (1, 2), (2, 0), (1, 0), (3, 3), (4, 5)];
        assert_eq!(cycles(6, &edges), vec![vec![0, 3], vec![4]]);
    }

    #[test]
    fn acyclic_graphs_and_stray_edges_give_nothing() {
        assert!(cycles(3, &[(0, 1), (1, 2), (0, 2)]).is_empty());
        assert!(cycles(2, &[(0, 7), (7, 0)]).is_empty());
        assert!(cycles(0, &[]).is_empty());
    }

    #[test]
    fn long_chains_do_not_recurse() {
        let n = 200_000;
        let mut edges: Vec<(usize, usize)> = (0..n - 1).map(|i| (i, i + 1)).collect();
        edges.push((n - 1, 0));
        let found = cycles(n, &edges);
        assert_eq!(found.len(), 1);
        assert_eq!(found[0].len(), n);
    }
}
