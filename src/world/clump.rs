//! Clumps: rigid grains made of overlapping disks, the non-convex grains of LMGC90's clusters,
//! PFC's and YADE's clumps. The union's area, centroid and moment come from Green's theorem
//! along the arcs that no other disk covers (exact for any overlap, holes included); the outer
//! loop of those arcs is the outline the outputs draw.

use glam::DVec2;
use std::f64::consts::TAU;

/// A clump's disks can be at most this many: the union is computed pairwise.
pub const MAX_CLUMP_DISKS: usize = 256;

/// A clump in its body frame (centroid at the origin).
#[derive(Clone, Debug)]
pub struct ClumpShape {
    /// The disks: centre in the body frame and radius.
    pub disks: Vec<(DVec2, f64)>,
    /// The union's outer boundary, counter-clockwise, in the body frame (pictures, VTK).
    pub outline: Vec<DVec2>,
}

/// Area, centroid, polar moment of area about the centroid, and the outer outline (in the
/// disks' frame) of a union of disks.
#[derive(Debug)]
pub(crate) struct DiskUnion {
    pub area: f64,
    pub centroid: DVec2,
    pub polar: f64,
    pub outline: Vec<DVec2>,
}

/// A clump's disks moved to their union's centroid and scaled to a bounding radius of 1: the
/// template a generator scales to each grain's radius.
pub fn unit_clump(disks: &[(DVec2, f64)]) -> Result<Vec<(DVec2, f64)>, String> {
    let centroid = disk_union(disks)?.centroid;
    let reach = disks.iter().map(|(c, r)| (*c - centroid).length() + r).fold(0.0, f64::max);
    Ok(disks.iter().map(|(c, r)| ((*c - centroid) / reach, r / reach)).collect())
}

/// An arc of circle `disk` from angle `from` to `to` (`to > from`), counter-clockwise.
struct Arc {
    center: DVec2,
    radius: f64,
    from: f64,
    to: f64,
}

impl Arc {
    fn at(&self, t: f64) -> DVec2 {
        self.center + self.radius * DVec2::from_angle(t)
    }
}

/// Refuses disks that are not finite and positive, too many, or that do not overlap into one
/// grain, naming the disk; returns the union's properties.
pub(crate) fn disk_union(disks: &[(DVec2, f64)]) -> Result<DiskUnion, String> {
    if disks.is_empty() || disks.len() > MAX_CLUMP_DISKS {
        return Err(format!("a clump needs 1 to {MAX_CLUMP_DISKS} disks, got {}", disks.len()));
    }
    for (k, (c, r)) in disks.iter().enumerate() {
        if !(c.is_finite() && r.is_finite() && *r > 0.0) {
            return Err(format!(
                "clump disk {k} (centre [{}, {}], radius {r}) needs a finite centre and radius > 0",
                c.x, c.y
            ));
        }
    }
    if let Some(k) = first_detached(disks) {
        return Err(format!(
            "clump disk {k} neither overlaps nor touches the disks before it: a clump's disks must make one grain"
        ));
    }
    let size = disks.iter().map(|(c, r)| c.length() + r).fold(0.0, f64::max);
    if !(size * size).is_finite() {
        return Err(format!("clump disks reach {size:e} m from the given centre: beyond f64, scale the lengths"));
    }
    let arcs = uncovered_arcs(disks);
    let (mut area, mut first, mut second) = (0.0, DVec2::ZERO, 0.0);
    for arc in &arcs {
        let (a, f, s) = green_integrals(arc);
        area += a;
        first += f;
        second += s;
    }
    let centroid = first / area;
    if !(area.is_finite() && area > 1e-12 * size * size) {
        return Err(format!("degenerate clump: area {area:e} for its size {size:e}"));
    }
    Ok(DiskUnion { area, centroid, polar: second - area * centroid.length_squared(), outline: outer_loop(&arcs, size) })
}

/// The first disk (in order) that no earlier disk reaches through a chain of overlaps.
fn first_detached(disks: &[(DVec2, f64)]) -> Option<usize> {
    let mut joined = vec![false; disks.len()];
    joined[0] = true;
    let mut stack = vec![0];
    while let Some(i) = stack.pop() {
        for j in 0..disks.len() {
            let (ci, ri) = disks[i];
            let (cj, rj) = disks[j];
            if !joined[j] && ci.distance(cj) <= (ri + rj) * (1.0 + 1e-12) {
                joined[j] = true;
                stack.push(j);
            }
        }
    }
    joined.iter().position(|j| !j)
}

/// The arcs of the disks' circles that lie inside no other disk: the union's boundary.
fn uncovered_arcs(disks: &[(DVec2, f64)]) -> Vec<Arc> {
    let inside = |i: usize, j: usize| {
        let ((ci, ri), (cj, rj)) = (disks[i], disks[j]);
        let d = ci.distance(cj);
        // Two equal disks: only the later one is inside the other.
        d + ri <= rj && !(d + rj <= ri && j > i)
    };
    let mut arcs = Vec::new();
    for (i, &(ci, ri)) in disks.iter().enumerate() {
        if (0..disks.len()).any(|j| j != i && inside(i, j)) {
            continue;
        }
        let mut covered: Vec<(f64, f64)> = Vec::new();
        for (j, &(cj, rj)) in disks.iter().enumerate() {
            let d = ci.distance(cj);
            if j == i || d >= ri + rj || d + rj <= ri {
                continue;
            }
            let half = ((ri * ri + d * d - rj * rj) / (2.0 * ri * d)).clamp(-1.0, 1.0).acos();
            let mid = (cj - ci).to_angle().rem_euclid(TAU);
            let from = (mid - half).rem_euclid(TAU);
            let to = from + 2.0 * half;
            if to > TAU {
                covered.extend([(from, TAU), (0.0, to - TAU)]);
            } else {
                covered.push((from, to));
            }
        }
        covered.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut free = Vec::new();
        let mut reached = 0.0;
        for (from, to) in covered {
            if from > reached {
                free.push((reached, from));
            }
            reached = f64::max(reached, to);
        }
        if reached < TAU {
            free.push((reached, TAU));
        }
        // An arc through angle 0 is one arc, not two.
        if free.len() > 1 && free[0].0 == 0.0 && free[free.len() - 1].1 == TAU {
            let last = free.pop().unwrap();
            free[0] = (last.0, free[0].1 + TAU);
        }
        arcs.extend(free.into_iter().filter(|(a, b)| b > a).map(|(from, to)| Arc { center: ci, radius: ri, from, to }));
    }
    arcs
}

/// Green's theorem along one arc: its share of the area, of `∫ x dA` and of `∫ |x|² dA`.
fn green_integrals(arc: &Arc) -> (f64, DVec2, f64) {
    // Five-point Gauss–Legendre on pieces of at most π/32: the integrands are trigonometric
    // polynomials of degree 4, integrated to rounding.
    const NODES: [f64; 5] =
        [0.0, -0.538_469_310_105_683_1, 0.538_469_310_105_683_1, -0.906_179_845_938_664, 0.906_179_845_938_664];
    const WEIGHTS: [f64; 5] = [
        0.568_888_888_888_888_9,
        0.478_628_670_499_366_5,
        0.478_628_670_499_366_5,
        0.236_926_885_056_189_1,
        0.236_926_885_056_189_1,
    ];
    let pieces = ((arc.to - arc.from) / (TAU / 64.0)).ceil().max(1.0) as usize;
    let width = (arc.to - arc.from) / pieces as f64;
    let (mut area, mut first, mut second) = (0.0, DVec2::ZERO, 0.0);
    for p in 0..pieces {
        let mid = arc.from + (p as f64 + 0.5) * width;
        for (x, w) in NODES.iter().zip(WEIGHTS) {
            let t = mid + 0.5 * width * x;
            let w = w * 0.5 * width;
            let pt = arc.at(t);
            let d = arc.radius * DVec2::new(-t.sin(), t.cos());
            area += w * 0.5 * pt.perp_dot(d);
            first += w * DVec2::new(0.5 * pt.x * pt.x * d.y, -0.5 * pt.y * pt.y * d.x);
            second += w * (pt.x.powi(3) * d.y - pt.y.powi(3) * d.x) / 3.0;
        }
    }
    (area, first, second)
}

/// The arcs chained end to start into loops; the one enclosing the most area, sampled every
/// π/16 at most.
fn outer_loop(arcs: &[Arc], size: f64) -> Vec<DVec2> {
    let mut used = vec![false; arcs.len()];
    let mut best: (f64, Vec<DVec2>) = (f64::NEG_INFINITY, Vec::new());
    while let Some(start) = used.iter().position(|u| !u) {
        let mut points = Vec::new();
        let mut k = start;
        loop {
            used[k] = true;
            let arc = &arcs[k];
            let steps = ((arc.to - arc.from) / (TAU / 32.0)).ceil().max(1.0) as usize;
            points.extend((0..steps).map(|s| arc.at(arc.from + (arc.to - arc.from) * s as f64 / steps as f64)));
            let end = arc.at(arc.to);
            let next = (0..arcs.len())
                .filter(|&n| !used[n])
                .map(|n| (arcs[n].at(arcs[n].from).distance(end), n))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            match next {
                Some((gap, n)) if gap <= 1e-9 * size && gap <= arcs[start].at(arcs[start].from).distance(end) => k = n,
                _ => break,
            }
        }
        let area = 0.5 * (0..points.len()).map(|k| points[k].perp_dot(points[(k + 1) % points.len()])).sum::<f64>();
        if area > best.0 {
            best = (area, points);
        }
    }
    best.1
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn one_disk_has_its_closed_form_area_and_moment() {
        let u = disk_union(&[(DVec2::new(0.3, -0.2), 0.5)]).unwrap();
        assert!((u.area - PI * 0.25).abs() < 1e-15, "{}", u.area);
        assert!((u.centroid - DVec2::new(0.3, -0.2)).length() < 1e-15);
        assert!((u.polar - PI * 0.5f64.powi(4) / 2.0).abs() < 1e-15, "{}", u.polar);
        assert!(u.outline.len() >= 32);
    }

    #[test]
    fn two_overlapping_disks_give_the_lens_formula() {
        // Equal disks of radius r, centres d apart: union = 2πr² − lens, lens = 2r² acos(d/2r) − (d/2)√(4r² − d²).
        let (r, d) = (1.0f64, 1.2);
        let lens = 2.0 * r * r * (d / (2.0 * r)).acos() - 0.5 * d * (4.0 * r * r - d * d).sqrt();
        let u = disk_union(&[(DVec2::ZERO, r), (DVec2::new(d, 0.0), r)]).unwrap();
        assert!((u.area - (2.0 * PI * r * r - lens)).abs() < 1e-13, "{} vs {}", u.area, 2.0 * PI - lens);
        assert!((u.centroid - DVec2::new(0.6, 0.0)).length() < 1e-14, "{:?}", u.centroid);
        // The outline's polygon is the union's shape to its sampling.
        let drawn = 0.5
            * (0..u.outline.len()).map(|k| u.outline[k].perp_dot(u.outline[(k + 1) % u.outline.len()])).sum::<f64>();
        assert!((drawn - u.area).abs() < 0.02 * u.area, "{drawn} vs {}", u.area);
    }

    #[test]
    fn touching_and_nested_disks_count_once() {
        // Tangent disks: the two areas and moments by the parallel-axis rule.
        let u = disk_union(&[(DVec2::new(-1.0, 0.0), 1.0), (DVec2::new(1.0, 0.0), 1.0)]).unwrap();
        assert!((u.area - 2.0 * PI).abs() < 1e-13 && u.centroid.length() < 1e-14);
        assert!((u.polar - 2.0 * (PI / 2.0 + PI)).abs() < 1e-12, "{}", u.polar);
        // A disk inside another, and a disk given twice, change nothing.
        let big = disk_union(&[(DVec2::ZERO, 2.0)]).unwrap();
        for disks in
            [vec![(DVec2::ZERO, 2.0), (DVec2::new(0.5, 0.5), 1.0)], vec![(DVec2::ZERO, 2.0), (DVec2::ZERO, 2.0)]]
        {
            let u = disk_union(&disks).unwrap();
            assert!((u.area - big.area).abs() < 1e-13 && (u.polar - big.polar).abs() < 1e-12, "{disks:?}");
        }
    }

    #[test]
    fn a_ring_of_disks_leaves_its_hole_out() {
        // Twelve disks on a circle, each overlapping its neighbours: the hole in the middle is
        // not matter. Checked against a fine grid count of the union.
        let disks: Vec<_> = (0..12).map(|k| (DVec2::from_angle(TAU * k as f64 / 12.0) * 3.0, 0.9)).collect();
        let u = disk_union(&disks).unwrap();
        let n = 1600;
        let cell = 8.0 / n as f64;
        let mut count = 0usize;
        for a in 0..n {
            for b in 0..n {
                let p = DVec2::new(-4.0 + (a as f64 + 0.5) * cell, -4.0 + (b as f64 + 0.5) * cell);
                count += usize::from(disks.iter().any(|(c, r)| p.distance(*c) <= *r));
            }
        }
        let grid = count as f64 * cell * cell;
        assert!((u.area - grid).abs() < 2e-3 * grid, "{} vs {grid}", u.area);
        assert!(u.centroid.length() < 1e-12);
        assert!(u.area < 12.0 * PI * 0.81, "overlaps counted once");
    }

    #[test]
    fn detached_and_bad_disks_are_refused_by_name() {
        let e =
            disk_union(&[(DVec2::ZERO, 1.0), (DVec2::new(1.5, 0.0), 1.0), (DVec2::new(5.0, 0.0), 1.0)]).unwrap_err();
        assert!(e.contains("clump disk 2") && e.contains("one grain"), "{e}");
        let e = disk_union(&[(DVec2::ZERO, 1.0), (DVec2::X, f64::NAN)]).unwrap_err();
        assert!(e.contains("clump disk 1"), "{e}");
        assert!(disk_union(&[]).unwrap_err().contains("1 to 256"));
        let e = disk_union(&[(DVec2::new(1e300, 0.0), 1.0), (DVec2::new(1e300, 0.5), 1.0)]).unwrap_err();
        assert!(e.contains("beyond f64"), "{e}");
    }
}
