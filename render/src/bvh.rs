//! Ray casting: every triangle of the scene (model and emitters) in one 4-wide BVH with
//! uncompressed float bounds, traversed with one 4-lane slab test per node (glam `Vec4`: SSE2 on
//! x86-64), and leaves of up to four triangles tested at once (Möller–Trumbore on precomputed
//! edges, four lanes).
//!
//! The tree comes from obvhs: a binary BVH (PLOC, spatial pre-splits, reinsertion, SAH leaf
//! collapse; `BvhBuildParams::very_slow_build` with at most [`MAX_LEAF`] triangles a leaf), which
//! is collapsed into 4-wide nodes by repeatedly opening the child with the largest surface area.
//! Closest-hit traversal visits children near to far and skips stacked entries that start beyond
//! the current closest hit; shadow rays stop at the first hit.

use std::mem::MaybeUninit;
use std::time::Duration;

use glam::{BVec4A, Vec3, Vec4};
use obvhs::bvh2::builder::build_bvh2_from_tris;
use obvhs::bvh2::Bvh2;
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;

/// Most triangles in one leaf.
pub const MAX_LEAF: u32 = 4;

/// One leaf: up to four triangles, lane i = triangle i (unused lanes are degenerate).
#[derive(Clone, Copy)]
#[repr(C, align(16))]
struct TriPack {
    p0: [Vec4; 3],
    e1: [Vec4; 3],
    e2: [Vec4; 3],
    prim: [u32; 4],
}

/// The closest hit of a ray.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub t: f32,
    /// Index into the triangle list given to [`Bvh::new`].
    pub prim: u32,
    /// Barycentric weights of vertices 1 and 2.
    pub b1: f32,
    pub b2: f32,
}

/// Child reference: an inner node index, or (with [`LEAF`]) a leaf's [`TriPack`] index.
const LEAF: u32 = 1 << 31;
/// An empty child slot (its bounds are inverted, so it is never entered).
const EMPTY: u32 = u32::MAX;

/// Four children's bounds, lane i = child i: min x, y, z then max x, y, z.
#[derive(Clone, Copy)]
#[repr(C, align(16))]
struct Node4 {
    bounds: [Vec4; 6],
    child: [u32; 4],
}

/// A BVH over triangles.
pub struct Bvh {
    nodes: Vec<Node4>,
    packs: Vec<TriPack>,
    depth: usize,
}

/// Möller–Trumbore against the four triangles of a pack: (t, u, v) per lane and the lanes hit
/// with `0 < t < tmax`.
#[inline(always)]
fn intersect4(pk: &TriPack, o: &[Vec4; 3], d: &[Vec4; 3], tmax: f32) -> (Vec4, Vec4, Vec4, u32) {
    let cross = |a: &[Vec4; 3], b: &[Vec4; 3]| {
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    };
    let dot = |a: &[Vec4; 3], b: &[Vec4; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let pvec = cross(d, &pk.e2);
    let det = dot(&pk.e1, &pvec);
    let inv = Vec4::ONE / det;
    let tvec = [o[0] - pk.p0[0], o[1] - pk.p0[1], o[2] - pk.p0[2]];
    let u = dot(&tvec, &pvec) * inv;
    let qvec = cross(&tvec, &pk.e1);
    let v = dot(d, &qvec) * inv;
    let t = dot(&pk.e2, &qvec) * inv;
    let ok = det.abs().cmpge(Vec4::splat(1e-14))
        & u.cmpge(Vec4::ZERO)
        & u.cmple(Vec4::ONE)
        & v.cmpge(Vec4::ZERO)
        & (u + v).cmple(Vec4::ONE)
        & t.cmpgt(Vec4::ZERO)
        & t.cmplt(Vec4::splat(tmax));
    (t, u, v, ok.bitmask())
}

/// 1/x, kept finite for (near) zero components like obvhs' `safe_inverse`.
#[inline(always)]
fn safe_inverse(x: f32) -> f32 {
    if x.abs() <= f32::EPSILON {
        x.signum() / f32::EPSILON
    } else {
        1.0 / x
    }
}

/// Per-ray constants of the slab test.
struct RayPre {
    /// Origin and 1/d per axis, splatted.
    org: [Vec4; 3],
    inv: [Vec4; 3],
    /// Index into `Node4::bounds` of the near and far plane per axis (by the direction's sign).
    near: [usize; 3],
    far: [usize; 3],
    dir: [Vec4; 3],
}

impl RayPre {
    #[inline(always)]
    fn new(o: Vec3, d: Vec3) -> Self {
        let inv = [safe_inverse(d.x), safe_inverse(d.y), safe_inverse(d.z)];
        let o = [o.x, o.y, o.z];
        let near = [0, 1, 2].map(|k| if inv[k] < 0.0 { k + 3 } else { k });
        RayPre {
            org: o.map(Vec4::splat),
            inv: inv.map(Vec4::splat),
            near,
            far: [0, 1, 2].map(|k| if near[k] >= 3 { k } else { k + 3 }),
            dir: [d.x, d.y, d.z].map(Vec4::splat),
        }
    }

    /// Entry distances of the four children and which of them the segment [0, tmax] enters.
    #[inline(always)]
    fn test(&self, node: &Node4, tmax: f32) -> (Vec4, BVec4A) {
        let b = &node.bounds;
        let t = |k: usize, i: usize| (b[i] - self.org[k]) * self.inv[k];
        let tn = t(0, self.near[0]).max(t(1, self.near[1])).max(t(2, self.near[2])).max(Vec4::ZERO);
        let tf = t(0, self.far[0]).min(t(1, self.far[1])).min(t(2, self.far[2]));
        // Widened by 1 + 2γ₃ so rounding never loses a box the ray grazes (Ize 2013).
        let tf = (tf * FAR_SCALE).min(Vec4::splat(tmax));
        (tn, tn.cmple(tf))
    }
}

/// How much the triangles' boxes overlap, as the mean number of them a random ray through the
/// scene's box crosses (their summed surface area over the scene box's), above which the build
/// runs without its quadratic passes. The dev rooms measure 4.8–7.2, their true geometry too. A
/// 60 000-vertex polygon (one fan of slivers; 9 550) took 14 s to build with them, 0.4 s without:
/// PLOC's wider pairing search and the reinsertion passes go quadratic when every box overlaps
/// the others.
const OVERLAP_LIMIT: f32 = 256.0;

/// obvhs' slowest, best build, with at most [`MAX_LEAF`] triangles a leaf; for heavily
/// overlapping boxes (see [`OVERLAP_LIMIT`]) its cheapest pairing and no reinsertion.
fn build_params(triangles: &[[Vec3; 3]]) -> BvhBuildParams {
    let mut params = if overlap(triangles) > OVERLAP_LIMIT {
        BvhBuildParams::fastest_build()
    } else {
        BvhBuildParams::very_slow_build()
    };
    params.max_prims_per_leaf = MAX_LEAF;
    params
}

/// Summed surface area of the triangles' boxes over the surface area of the scene's box (0 for
/// a scene with no extent).
fn overlap(triangles: &[[Vec3; 3]]) -> f32 {
    let area = |lo: Vec3, hi: Vec3| {
        let d = (hi - lo).max(Vec3::ZERO);
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    };
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    let mut boxes = 0.0f64;
    for t in triangles {
        let (tlo, thi) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
        boxes += f64::from(area(tlo, thi));
        (lo, hi) = (lo.min(tlo), hi.max(thi));
    }
    let scene = f64::from(area(lo, hi));
    if scene > 0.0 && scene.is_finite() {
        (boxes / scene) as f32
    } else {
        0.0
    }
}

/// Traversal stack entries kept on the call stack (at most 3 a level plus one): enough for any
/// tree of depth ≤ 85. Deeper trees (degenerate meshes: thousands of coincident triangles)
/// traverse with a heap-allocated stack of [`Bvh::stack_len`] entries instead.
const STACK: usize = 256;
const FAR_SCALE: f32 = 1.0 + 2.0 * 3.0 * f32::EPSILON * 0.5 / (1.0 - 3.0 * f32::EPSILON * 0.5);

impl Bvh {
    pub fn new(triangles: &[[Vec3; 3]]) -> Self {
        Bvh::build(triangles, build_params(triangles))
    }

    fn build(triangles: &[[Vec3; 3]], params: BvhBuildParams) -> Self {
        let tris: Vec<Triangle> = triangles
            .iter()
            .map(|t| Triangle { v0: t[0].to_array().into(), v1: t[1].to_array().into(), v2: t[2].to_array().into() })
            .collect();
        if tris.is_empty() {
            return Bvh { nodes: Vec::new(), packs: Vec::new(), depth: 0 };
        }
        let bvh2 = build_bvh2_from_tris(&tris, params, &mut Duration::default());
        let mut out = Bvh { nodes: Vec::new(), packs: Vec::new(), depth: 0 };
        let root = &bvh2.nodes[0];
        if root.is_leaf() {
            // A single leaf: one node with one child.
            let mut node = empty_node();
            set_child(&mut node, 0, &bvh2, 0, &mut out.packs, triangles);
            out.nodes.push(node);
        } else {
            out.collapse(&bvh2, 0, triangles);
        }
        out
    }

    /// Traversal stack entries a ray may need in this tree.
    fn stack_len(&self) -> usize {
        3 * self.depth + 1
    }

    /// Appends 4-wide nodes for the subtree of binary inner node `root`. Iterative, so that
    /// degenerate meshes (a binary tree thousands of levels deep) cannot overflow the stack.
    fn collapse(&mut self, bvh2: &Bvh2, root: usize, triangles: &[[Vec3; 3]]) {
        // (binary node, depth, parent 4-wide node and slot to link it from)
        // (binary node, depth, the 4-wide parent's (node, slot) to link it into)
        type Work = (usize, usize, Option<(usize, usize)>);
        let mut work: Vec<Work> = vec![(root, 1, None)];
        while let Some((n, depth, parent)) = work.pop() {
            self.depth = self.depth.max(depth);
            let first = bvh2.nodes[n].first_index as usize;
            let mut kids = vec![first, first + 1];
            while kids.len() < 4 {
                // Open the inner child with the largest surface area.
                let best = kids
                    .iter()
                    .enumerate()
                    .filter(|(_, &k)| !bvh2.nodes[k].is_leaf())
                    .max_by(|a, b| {
                        let (ha, hb) = (bvh2.nodes[*a.1].aabb().half_area(), bvh2.nodes[*b.1].aabb().half_area());
                        ha.total_cmp(&hb)
                    })
                    .map(|(i, _)| i);
                let Some(i) = best else { break };
                let k = kids.swap_remove(i);
                let c = bvh2.nodes[k].first_index as usize;
                kids.extend([c, c + 1]);
            }
            let index = self.nodes.len();
            if let Some((p, slot)) = parent {
                self.nodes[p].child[slot] = index as u32;
            }
            let mut node = empty_node();
            for (slot, &k) in kids.iter().enumerate() {
                if bvh2.nodes[k].is_leaf() {
                    set_child(&mut node, slot, bvh2, k, &mut self.packs, triangles);
                } else {
                    set_bounds(&mut node, slot, bvh2, k);
                    work.push((k, depth + 1, Some((index, slot))));
                }
            }
            self.nodes.push(node);
        }
    }

    /// Closest hit with `0 < t < tmax`; `d` must be unit length for `t` to be a distance.
    #[inline(always)]
    pub fn intersect(&self, o: Vec3, d: Vec3, tmax: f32) -> Option<Hit> {
        if self.nodes.is_empty() {
            return None;
        }
        let pre = RayPre::new(o, d);
        let mut tmax = tmax;
        let mut best: Option<(u32, f32, f32)> = None;
        let mut local = [MaybeUninit::<(u32, f32)>::uninit(); STACK];
        let mut heap = Vec::new();
        let stack = traversal_stack(&mut local, &mut heap, self.stack_len());
        stack[0].write((0, 0.0));
        let mut sp = 1usize;
        while sp > 0 {
            sp -= 1;
            // SAFETY: entries below `sp` were written.
            let (child, t_enter) = unsafe { stack[sp].assume_init() };
            if t_enter >= tmax {
                continue;
            }
            if child & LEAF != 0 {
                let pk = &self.packs[(child & !LEAF) as usize];
                let (t, u, v, mut mask) = intersect4(pk, &pre.org, &pre.dir, tmax);
                while mask != 0 {
                    let i = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    if t[i] < tmax {
                        tmax = t[i];
                        best = Some((pk.prim[i], u[i], v[i]));
                    }
                }
                continue;
            }
            let node = &self.nodes[child as usize];
            let (tn, hit) = pre.test(node, tmax);
            let mask = hit.bitmask();
            if mask == 0 {
                continue;
            }
            // Push the entered children far to near, so the nearest is popped first.
            let tn = tn.to_array();
            let mut order = [0usize; 4];
            let mut n = 0;
            for i in 0..4 {
                if mask & (1 << i) != 0 {
                    let mut j = n;
                    while j > 0 && tn[order[j - 1]] < tn[i] {
                        order[j] = order[j - 1];
                        j -= 1;
                    }
                    order[j] = i;
                    n += 1;
                }
            }
            for &i in &order[..n] {
                stack[sp].write((node.child[i], tn[i]));
                sp += 1;
            }
        }
        best.map(|(prim, b1, b2)| Hit { t: tmax, prim, b1, b2 })
    }

    /// Whether anything lies on the segment `0 < t < tmax`.
    #[inline(always)]
    pub fn occluded(&self, o: Vec3, d: Vec3, tmax: f32) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let pre = RayPre::new(o, d);
        let mut local = [MaybeUninit::<u32>::uninit(); STACK];
        let mut heap = Vec::new();
        let stack = traversal_stack(&mut local, &mut heap, self.stack_len());
        stack[0].write(0);
        let mut sp = 1usize;
        while sp > 0 {
            sp -= 1;
            // SAFETY: entries below `sp` were written.
            let child = unsafe { stack[sp].assume_init() };
            if child & LEAF != 0 {
                if intersect4(&self.packs[(child & !LEAF) as usize], &pre.org, &pre.dir, tmax).3 != 0 {
                    return true;
                }
                continue;
            }
            let node = &self.nodes[child as usize];
            let mask = pre.test(node, tmax).1.bitmask();
            for i in 0..4 {
                if mask & (1 << i) != 0 {
                    stack[sp].write(node.child[i]);
                    sp += 1;
                }
            }
        }
        false
    }
}

/// The call-stack array when the tree is shallow enough (always, for sane meshes), else a heap
/// buffer of `len` entries.
#[inline(always)]
fn traversal_stack<'a, T: Copy>(
    local: &'a mut [MaybeUninit<T>; STACK],
    heap: &'a mut Vec<MaybeUninit<T>>,
    len: usize,
) -> &'a mut [MaybeUninit<T>] {
    if len <= STACK {
        local
    } else {
        heap.resize(len, MaybeUninit::uninit());
        heap
    }
}

fn empty_node() -> Node4 {
    let (lo, hi) = (Vec4::splat(f32::INFINITY), Vec4::splat(f32::NEG_INFINITY));
    Node4 { bounds: [lo, lo, lo, hi, hi, hi], child: [EMPTY; 4] }
}

fn set_bounds(node: &mut Node4, slot: usize, bvh2: &Bvh2, k: usize) {
    let b = bvh2.nodes[k].aabb();
    for axis in 0..3 {
        node.bounds[axis][slot] = b.min[axis];
        node.bounds[axis + 3][slot] = b.max[axis];
    }
}

/// Make `slot` the leaf of binary node `k`, appending its triangles to `packs`.
fn set_child(node: &mut Node4, slot: usize, bvh2: &Bvh2, k: usize, packs: &mut Vec<TriPack>, triangles: &[[Vec3; 3]]) {
    set_bounds(node, slot, bvh2, k);
    let leaf = &bvh2.nodes[k];
    let (first, count) = (leaf.first_index as usize, leaf.prim_count as usize);
    assert!((1..=MAX_LEAF as usize).contains(&count), "BVH leaf of {count} triangles");
    let mut pk = TriPack { p0: [Vec4::ZERO; 3], e1: [Vec4::ZERO; 3], e2: [Vec4::ZERO; 3], prim: [u32::MAX; 4] };
    for (lane, &i) in bvh2.primitive_indices[first..first + count].iter().enumerate() {
        let t = &triangles[i as usize];
        let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
        for axis in 0..3 {
            pk.p0[axis][lane] = t[0][axis];
            pk.e1[axis][lane] = e1[axis];
            pk.e2[axis][lane] = e2[axis];
        }
        pk.prim[lane] = i;
    }
    assert!(packs.len() < LEAF as usize, "too many BVH leaves");
    node.child[slot] = LEAF | packs.len() as u32;
    packs.push(pk);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Degenerate meshes make binary trees thousands of levels deep: building must not
    /// overflow the stack and traversal must still find the closest hit.
    #[test]
    fn coincident_triangles_build_and_trace() {
        let mut tris: Vec<[Vec3; 3]> = (0..2_000).map(|_| [Vec3::ZERO, Vec3::X, Vec3::Y]).collect();
        tris.push([Vec3::new(0.0, 0.0, 0.5), Vec3::new(1.0, 0.0, 0.5), Vec3::new(0.0, 1.0, 0.5)]);
        // The slow build (the default's for scenes whose boxes overlap less) makes the deepest tree.
        let bvh =
            Bvh::build(&tris, BvhBuildParams { max_prims_per_leaf: MAX_LEAF, ..BvhBuildParams::very_slow_build() });
        assert!(bvh.stack_len() > STACK, "the test must exercise the deep-tree path (depth {})", bvh.depth);
        let hit = bvh.intersect(Vec3::new(0.2, 0.2, 1.0), Vec3::NEG_Z, f32::INFINITY).expect("a hit");
        assert_eq!(hit.prim, 2_000);
        assert!((hit.t - 0.5).abs() < 1e-5);
        let below = bvh.intersect(Vec3::new(0.2, 0.2, 0.25), Vec3::NEG_Z, f32::INFINITY).expect("a hit");
        assert!(below.prim < 2_000 && (below.t - 0.25).abs() < 1e-5);
        assert!(bvh.occluded(Vec3::new(0.2, 0.2, 1.0), Vec3::NEG_Z, 0.9));
        assert!(!bvh.occluded(Vec3::new(0.2, 0.2, 1.0), Vec3::NEG_Z, 0.4));
    }

    /// A large polygon triangulated as one fan: every box overlaps every other, so the tree is
    /// built without the quadratic passes, and rays still find the closest sliver.
    #[test]
    fn a_fan_of_slivers_builds_cheaply_and_traces() {
        let n = 20_000;
        let rim = |i: usize| {
            let a = std::f32::consts::TAU * i as f32 / n as f32;
            Vec3::new(a.cos(), 0.0, a.sin())
        };
        let mut tris: Vec<[Vec3; 3]> = (1..n - 1).map(|i| [rim(0), rim(i), rim(i + 1)]).collect();
        assert!(overlap(&tris) > OVERLAP_LIMIT, "{}", overlap(&tris));
        let params = build_params(&tris);
        assert_eq!((params.reinsertion_batch_ratio, params.pre_split), (0.0, false));
        // A small square above the fan: a ray from above hits it first, then the fan.
        let s = 0.05;
        tris.push([Vec3::new(-s, 0.5, -s), Vec3::new(s, 0.5, -s), Vec3::new(-s, 0.5, s)]);
        let bvh = Bvh::new(&tris);
        let hit = bvh.intersect(Vec3::new(-0.01, 1.0, -0.01), Vec3::NEG_Y, f32::INFINITY).expect("a hit");
        assert_eq!(hit.prim as usize, tris.len() - 1);
        let fan = bvh.intersect(Vec3::new(0.3, 0.4, 0.2), Vec3::NEG_Y, f32::INFINITY).expect("a hit");
        // Slivers a ten-thousandth of a radian wide: Möller–Trumbore loses a few digits of t.
        assert!((fan.t - 0.4).abs() < 1e-3 && (fan.prim as usize) < tris.len() - 1, "{:?} {}", fan.t, fan.prim);
        // The fan covers the disc from rim(0): the chord to rim(k) leaves it at angle π/2 + πk/n
        // (inscribed angles), so the point lies in triangle k = floor(n (φ − π/2) / π), prim k − 1.
        let phi = 0.2f32.atan2(0.3 - 1.0);
        let k = (n as f32 * (phi - std::f32::consts::FRAC_PI_2) / std::f32::consts::PI) as usize;
        assert!((fan.prim as usize + 1).abs_diff(k) <= 1, "{} against {}", fan.prim, k - 1);
    }
}
