//! A 4-wide BVH: every node keeps the boxes of its (up to) four children
//! side by side, one array per axis and side, so that one pass of vector
//! code handles all four. Built by collapsing a binary [`Bvh`]; a child is
//! a node, a single object or a small leaf of objects (a binary leaf that
//! did not fit into its parent), so most objects need no node of their own.

use super::Aabb;
use super::bvh::{Bvh, NodeContent, round_down, round_up};

/// One child of a [`Node4`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Slot {
    Empty,
    /// Index of a node.
    Node(u32),
    /// Object id.
    Object(u32),
    /// Objects `items[first..first + count]` of the tree.
    Leaf {
        first: u32,
        count: u32,
    },
}

/// Four child boxes in f32 (rounded outwards, so each holds what its f64
/// box held) and the children: 112 bytes, two cache lines.
#[derive(Debug, Clone)]
#[repr(C, align(128))]
pub struct Node4 {
    /// `min[axis][slot]`; an empty slot has the inverted box
    /// (+∞ … −∞), which every overlap test rejects.
    pub min: [[f32; 4]; 3],
    pub max: [[f32; 4]; 3],
    /// Packed [`Slot`]s: see [`Node4::slot`].
    slots: [u32; 4],
}

/// Packing of a [`Slot`] in a `u32`: nodes have the top bit clear, objects
/// the top bit alone, leaves the top two bits, their count − 1 in the next
/// three and their first item in the rest.
const OBJECT: u32 = 1 << 31;
const LEAF: u32 = 1 << 30;
const LEAF_FIRST_BITS: u32 = 27;
/// Most objects in one leaf slot.
pub const LEAF_MAX: usize = 8;
const EMPTY: u32 = u32::MAX;

impl Node4 {
    /// An empty node.
    pub fn empty() -> Node4 {
        Node4 {
            min: [[f32::INFINITY; 4]; 3],
            max: [[f32::NEG_INFINITY; 4]; 3],
            slots: [EMPTY; 4],
        }
    }

    #[inline]
    pub fn slot(&self, s: usize) -> Slot {
        match self.slots[s] {
            EMPTY => Slot::Empty,
            v if v & (OBJECT | LEAF) == OBJECT | LEAF => Slot::Leaf {
                first: v & ((1 << LEAF_FIRST_BITS) - 1),
                count: ((v >> LEAF_FIRST_BITS) & 7) + 1,
            },
            v if v & OBJECT != 0 => Slot::Object(v & !OBJECT),
            v => Slot::Node(v),
        }
    }

    /// This node in a tree whose nodes and items start `nodes` and `items`
    /// later.
    fn shifted(mut self, nodes: u32, items: u32) -> Node4 {
        for v in &mut self.slots {
            if *v == EMPTY {
                continue;
            }
            if *v & OBJECT == 0 {
                *v += nodes;
                assert!(*v < OBJECT, "node index {v} out of range");
            } else if *v & LEAF != 0 {
                let first = (*v & ((1 << LEAF_FIRST_BITS) - 1)) + items;
                assert!(
                    first < (1 << LEAF_FIRST_BITS) - 1,
                    "leaf {first} out of range"
                );
                *v = (*v & !((1 << LEAF_FIRST_BITS) - 1)) | first;
            }
        }
        self
    }

    /// Sets child `s` and its box (rounded outwards to f32).
    pub fn set(&mut self, s: usize, slot: Slot, b: &Aabb) {
        self.slots[s] = match slot {
            Slot::Empty => EMPTY,
            Slot::Node(n) => {
                assert!(n < OBJECT, "node index {n} out of range");
                n
            }
            Slot::Object(o) => {
                assert!(o < LEAF, "object id {o} out of range");
                o | OBJECT
            }
            Slot::Leaf { first, count } => {
                assert!(
                    first < (1 << LEAF_FIRST_BITS) - 1 && (1..=LEAF_MAX as u32).contains(&count),
                    "leaf {first}+{count} out of range"
                );
                OBJECT | LEAF | ((count - 1) << LEAF_FIRST_BITS) | first
            }
        };
        for axis in 0..3 {
            self.min[axis][s] = round_down(b.min[axis]);
            self.max[axis][s] = round_up(b.max[axis]);
        }
    }
}

#[derive(Debug, Clone, Default)]
pub struct Bvh4 {
    /// The root is node 0 (none for an empty tree).
    pub nodes: Vec<Node4>,
    /// Object ids of the leaf slots.
    pub items: Vec<u32>,
}

/// A child while collapsing: a node of the binary tree, an object, or a
/// group of children (part of a binary leaf holding more than four).
#[derive(Clone)]
enum Pending {
    Node(u32),
    Object(u32),
    Group(Vec<(Aabb, Pending)>),
}

impl Bvh4 {
    /// Collapses `bvh`; `object_bounds(id)` is the box it was built from.
    /// The root's subtrees are collapsed on all threads; the tree is the
    /// one-thread collapse's, node for node (tested).
    pub fn from_binary(bvh: &Bvh, object_bounds: impl Fn(u32) -> Aabb + Sync) -> Bvh4 {
        let mut tree = Self::with_room(bvh);
        if !bvh.is_empty() {
            tree.collapse_root(bvh, &object_bounds);
        }
        tree
    }

    /// An empty tree with room for the collapse of `bvh`: every node stands
    /// for at least one inner binary node. Reserved at once, since a node's
    /// 128-byte alignment makes every regrowth a copy (the pages never
    /// written are not taken from the system, so a subtree's tree may
    /// reserve as much).
    fn with_room(bvh: &Bvh) -> Bvh4 {
        Bvh4 {
            nodes: Vec::with_capacity(bvh.node_count() / 2 + 1),
            items: Vec::new(),
        }
    }

    /// [`Bvh4::collapse`] of the root, its subtrees each on a thread: the
    /// first into this tree, the others into trees of their own, appended
    /// in slot order (so every node and item lands where the one-thread
    /// collapse puts it).
    fn collapse_root(&mut self, bvh: &Bvh, object_bounds: &(impl Fn(u32) -> Aabb + Sync)) {
        use rayon::prelude::*;
        let children = Self::open(bvh, object_bounds, Self::expand(bvh, object_bounds, 0));
        self.nodes.push(Node4::empty());
        let mut children = children.into_iter().enumerate();
        // Slots up to the first subtree in turn, as the one-thread collapse.
        let mut head = None;
        for (s, (b, p)) in children.by_ref() {
            match self.slot_or_subtree(bvh, object_bounds, p) {
                Ok(slot) => self.nodes[0].set(s, slot, &b),
                Err(content) => {
                    head = Some((s, b, content));
                    break;
                }
            }
        }
        let Some((head_slot, head_box, head)) = head else {
            return;
        };
        // The later slots: subtrees (`None`, collapsed on their own) and
        // the others, whose items must follow the subtrees before them.
        let mut later: Vec<(usize, Aabb, Option<Pending>)> = Vec::new();
        let mut subtrees = Vec::new();
        for (s, (b, p)) in children {
            let content = match p {
                Pending::Group(g) => Ok(g),
                Pending::Node(n) if Self::becomes_node(bvh, n) => {
                    Ok(Self::expand(bvh, object_bounds, n))
                }
                p => Err(p),
            };
            match content {
                Ok(c) => {
                    subtrees.push(c);
                    later.push((s, b, None));
                }
                Err(p) => later.push((s, b, Some(p))),
            }
        }
        let (head_root, trees) = rayon::join(
            || self.collapse(bvh, object_bounds, head),
            || {
                subtrees
                    .into_par_iter()
                    .map(|c| {
                        let mut t = Self::with_room(bvh);
                        t.collapse(bvh, object_bounds, c);
                        t
                    })
                    .collect::<Vec<Bvh4>>()
            },
        );
        self.nodes[0].set(head_slot, Slot::Node(head_root), &head_box);
        let mut trees = trees.into_iter();
        for (s, b, p) in later {
            let slot = match p {
                Some(p) => match self.slot_or_subtree(bvh, object_bounds, p) {
                    Ok(slot) => slot,
                    Err(_) => unreachable!("an object or a small leaf"),
                },
                None => Slot::Node(self.append(trees.next().expect("a later subtree"))),
            };
            self.nodes[0].set(s, slot, &b);
        }
    }

    /// Appends `tree` (its node and item indices shifted past this tree's);
    /// returns the index of its root.
    fn append(&mut self, tree: Bvh4) -> u32 {
        let (nodes, items) = (self.nodes.len() as u32, self.items.len() as u32);
        self.nodes
            .extend(tree.nodes.into_iter().map(|n| n.shifted(nodes, items)));
        self.items.extend(tree.items);
        nodes
    }

    /// Nodes and items, for memory figures.
    pub fn size_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Node4>() + self.items.len() * 4
    }

    /// The children a binary node stands for.
    fn expand(bvh: &Bvh, object_bounds: &impl Fn(u32) -> Aabb, node: u32) -> Vec<(Aabb, Pending)> {
        match bvh.node(node).1 {
            NodeContent::Leaf(objects) => objects
                .iter()
                .map(|&o| (object_bounds(o), Pending::Object(o)))
                .collect(),
            NodeContent::Inner(children) => children
                .iter()
                .map(|&c| (bvh.node(c).0, Pending::Node(c)))
                .collect(),
        }
    }

    /// Adds a node over `children`; returns its index.
    fn collapse(
        &mut self,
        bvh: &Bvh,
        object_bounds: &impl Fn(u32) -> Aabb,
        children: Vec<(Aabb, Pending)>,
    ) -> u32 {
        let children = Self::open(bvh, object_bounds, children);
        let index = self.nodes.len() as u32;
        self.nodes.push(Node4::empty());
        for (s, (b, p)) in children.into_iter().enumerate() {
            let slot = match self.slot_or_subtree(bvh, object_bounds, p) {
                Ok(slot) => slot,
                Err(content) => Slot::Node(self.collapse(bvh, object_bounds, content)),
            };
            self.nodes[index as usize].set(s, slot, &b);
        }
        index
    }

    /// The (at most four) children of a node over `children`.
    fn open(
        bvh: &Bvh,
        object_bounds: &impl Fn(u32) -> Aabb,
        mut children: Vec<(Aabb, Pending)>,
    ) -> Vec<(Aabb, Pending)> {
        if children.len() > 4 {
            // A large leaf (SAH keeps up to 8 objects, and any number whose
            // centres coincide): four groups, each a node of its own.
            let per = children.len().div_ceil(4);
            let mut groups = Vec::with_capacity(4);
            while !children.is_empty() {
                let rest = children.split_off(per.min(children.len()));
                let group = std::mem::replace(&mut children, rest);
                let b = group.iter().fold(Aabb::EMPTY, |b, c| b.union(c.0));
                groups.push((b, Pending::Group(group)));
            }
            children = groups;
        }
        // Open the largest child while its content still fits: the tree
        // gets about half as deep, and leaves dissolve into objects.
        loop {
            let size = |p: &Pending| match p {
                Pending::Node(n) => match bvh.node(*n).1 {
                    NodeContent::Leaf(objects) => objects.len(),
                    NodeContent::Inner(_) => 2,
                },
                Pending::Group(g) => g.len(),
                Pending::Object(_) => usize::MAX,
            };
            let Some((k, _)) = children
                .iter()
                .enumerate()
                .filter(|(_, (_, p))| size(p) != usize::MAX && children.len() - 1 + size(p) <= 4)
                .max_by(|a, b| a.1.0.surface_area().total_cmp(&b.1.0.surface_area()))
            else {
                break;
            };
            let (_, opened) = children.swap_remove(k);
            match opened {
                Pending::Node(n) => children.extend(Self::expand(bvh, object_bounds, n)),
                Pending::Group(g) => children.extend(g),
                Pending::Object(_) => unreachable!("objects do not open"),
            }
        }
        children
    }

    /// The slot of child `p` (a small binary leaf's objects appended to the
    /// items), or the children of the node it becomes.
    fn slot_or_subtree(
        &mut self,
        bvh: &Bvh,
        object_bounds: &impl Fn(u32) -> Aabb,
        p: Pending,
    ) -> Result<Slot, Vec<(Aabb, Pending)>> {
        match p {
            Pending::Object(o) => Ok(Slot::Object(o)),
            Pending::Node(n) => match bvh.node(n).1 {
                _ if Self::becomes_node(bvh, n) => Err(Self::expand(bvh, object_bounds, n)),
                NodeContent::Leaf(objects) => {
                    let first = self.items.len() as u32;
                    self.items.extend_from_slice(objects);
                    Ok(Slot::Leaf {
                        first,
                        count: objects.len() as u32,
                    })
                }
                NodeContent::Inner(_) => unreachable!("an inner node becomes a node"),
            },
            Pending::Group(g) => Err(g),
        }
    }

    /// Whether binary node `n`, a child that stays closed, becomes a node
    /// (else a small leaf that did not fit: a leaf slot).
    fn becomes_node(bvh: &Bvh, n: u32) -> bool {
        !matches!(bvh.node(n).1, NodeContent::Leaf(objects) if objects.len() <= LEAF_MAX)
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;

    /// The 4-wide tree over objects with these bounds (ids 0, 1, …).
    fn tree_of(bounds: &[Aabb]) -> Bvh4 {
        let items: Vec<(u32, Aabb)> = bounds
            .iter()
            .enumerate()
            .map(|(i, b)| (i as u32, *b))
            .collect();
        Bvh4::from_binary(&Bvh::build(&items), |i| bounds[i as usize])
    }

    /// Many objects with one centre make one binary leaf; the 4-wide tree
    /// splits it into nodes of at most four.
    #[test]
    fn a_large_leaf_becomes_nodes_of_four() {
        let bounds: Vec<Aabb> = (1..=300)
            .map(|i| Aabb::new(DVec3::splat(-(i as f64)), DVec3::splat(i as f64)))
            .collect();
        let tree = tree_of(&bounds);
        let objects: Vec<u32> = tree
            .nodes
            .iter()
            .flat_map(|n| (0..4).map(|s| n.slot(s)))
            .flat_map(|s| match s {
                Slot::Object(o) => vec![o],
                Slot::Leaf { first, count } => {
                    tree.items[first as usize..(first + count) as usize].to_vec()
                }
                _ => vec![],
            })
            .collect();
        assert_eq!(objects.len(), 300);
        let mut sorted = objects.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), 300);
    }

    /// Boxes scattered by a hash, of sizes spread over two decades.
    fn scattered(n: u32) -> Vec<Aabb> {
        (0..n)
            .map(|i| {
                let h =
                    |k: u32| ((i.wrapping_mul(2654435761).rotate_left(k) % 1000) as f64) / 100.0;
                let c = DVec3::new(h(0), h(7), h(13));
                Aabb::new(c - 0.01 * (1.0 + h(21)), c + 0.01 * (1.0 + h(27)))
            })
            .collect()
    }

    #[test]
    fn the_parallel_collapse_is_the_one_thread_collapse() {
        let mut layouts = vec![scattered(5000), scattered(37)];
        // One binary leaf of 300: the root's children are groups.
        layouts.push(
            (1..=300)
                .map(|i| Aabb::new(DVec3::splat(-(i as f64)), DVec3::splat(i as f64)))
                .collect(),
        );
        for bounds in &layouts {
            let items: Vec<(u32, Aabb)> = bounds
                .iter()
                .enumerate()
                .map(|(i, b)| (i as u32, *b))
                .collect();
            let bvh = Bvh::build(&items);
            let of = |i: u32| bounds[i as usize];
            let parallel = Bvh4::from_binary(&bvh, of);
            let mut serial = Bvh4::with_room(&bvh);
            serial.collapse(&bvh, &of, Bvh4::expand(&bvh, &of, 0));
            assert!(serial.nodes.len() > 1, "a root with subtrees");
            assert_eq!(parallel.items, serial.items);
            assert_eq!(parallel.nodes.len(), serial.nodes.len());
            for (p, s) in parallel.nodes.iter().zip(&serial.nodes) {
                assert_eq!(p.slots, s.slots);
                assert_eq!(
                    p.min.map(|a| a.map(f32::to_bits)),
                    s.min.map(|a| a.map(f32::to_bits))
                );
                assert_eq!(
                    p.max.map(|a| a.map(f32::to_bits)),
                    s.max.map(|a| a.map(f32::to_bits))
                );
            }
        }
    }

    #[test]
    fn slots_pack_and_unpack() {
        let mut n = Node4::empty();
        let b = Aabb::new(DVec3::ZERO, DVec3::ONE);
        let slots = [
            Slot::Node(7),
            Slot::Object((1 << 30) - 1),
            Slot::Leaf {
                first: (1 << 27) - 2,
                count: 8,
            },
            Slot::Leaf { first: 0, count: 1 },
        ];
        for (s, slot) in slots.iter().enumerate() {
            n.set(s, *slot, &b);
        }
        for (s, slot) in slots.iter().enumerate() {
            assert_eq!(n.slot(s), *slot);
        }
        assert_eq!(Node4::empty().slot(0), Slot::Empty);
    }

    #[test]
    fn f32_boxes_round_outwards() {
        for x in [0.1, -0.1, 1e9 + 0.5, -3e-40, 7.0, 1e300] {
            assert!(
                (round_down(x) as f64) <= x && (round_up(x) as f64) >= x,
                "{x}"
            );
        }
        assert_eq!(round_down(f64::INFINITY), f32::INFINITY);
        assert_eq!(round_up(f64::NEG_INFINITY), f32::NEG_INFINITY);
    }

    #[test]
    fn collapse_keeps_every_object_once_inside_its_parents_boxes() {
        let mut bounds = Vec::new();
        for i in 0..1000u32 {
            let h = |k: u32| ((i.wrapping_mul(2654435761).rotate_left(k) % 1000) as f64) / 100.0;
            let c = DVec3::new(h(0), h(7), h(13));
            bounds.push(Aabb::new(c - 0.05, c + 0.05));
        }
        let tree = tree_of(&bounds);
        let mut seen = vec![0; bounds.len()];
        // Walk from the root, checking each slot's box holds what is below.
        fn walk(tree: &Bvh4, n: u32, bounds: &[Aabb], seen: &mut [u32]) -> Aabb {
            let node = &tree.nodes[n as usize];
            let mut all = Aabb::EMPTY;
            for s in 0..4 {
                let corner =
                    |v: &[[f32; 4]; 3]| DVec3::new(v[0][s] as f64, v[1][s] as f64, v[2][s] as f64);
                let slot_box = Aabb::new(corner(&node.min), corner(&node.max));
                let inner = match node.slot(s) {
                    Slot::Empty => continue,
                    Slot::Object(o) => {
                        seen[o as usize] += 1;
                        bounds[o as usize]
                    }
                    Slot::Leaf { first, count } => {
                        let ids = &tree.items[first as usize..(first + count) as usize];
                        ids.iter().fold(Aabb::EMPTY, |b, &o| {
                            seen[o as usize] += 1;
                            b.union(bounds[o as usize])
                        })
                    }
                    Slot::Node(c) => walk(tree, c, bounds, seen),
                };
                assert!(slot_box.min.cmple(inner.min).all() && slot_box.max.cmpge(inner.max).all());
                all = all.union(slot_box);
            }
            all
        }
        walk(&tree, 0, &bounds, &mut seen);
        assert!(seen.iter().all(|&n| n == 1));
        // Four-wide: far fewer nodes than the binary tree's ~2N/4·2.
        assert!(tree.nodes.len() < 500, "{}", tree.nodes.len());
        let full = tree
            .nodes
            .iter()
            .flat_map(|n| (0..4).map(|s| n.slot(s)))
            .filter(|s| *s != Slot::Empty)
            .count();
        assert!(
            full as f64 > 3.0 * tree.nodes.len() as f64,
            "mostly full nodes"
        );
    }
}
