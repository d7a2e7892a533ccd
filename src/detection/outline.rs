//! Contacts of polygons, convex or not, with polygons and segments, read from their outlines
//! (node-to-segment, as finite-element contact does): each convex corner of one body against each
//! edge of the other it faces, and corner against corner where neither meets an edge. A corner
//! inside the other body meets the face it crossed and the faces still ahead of it. Blocks laid
//! face to face, their corners coincident to roundings, meet at both ends of the joint, once each.
//! Every corner that may reach a face within the step is a contact at its start, where separating
//! axes and clipping kept only the two ends of one incident edge: a hexagon spinning at 60 rad/s
//! brought its next corner through the face unseen. Convex pieces cut from a concave body would
//! not do either: their inner edges give normals that push a corner sideways into a notch. Here a
//! notch's two sides both hold the corner in it (BENCHMARKS.md, "Concave polygons").

use glam::DVec2;

/// A closed outline in the world frame: counter-clockwise vertices (two for a two-sided
/// segment), and which of them are convex corners (empty: all are).
#[derive(Clone, Copy)]
pub struct Outline<'a> {
    /// Vertices, counter-clockwise.
    pub points: &'a [DVec2],
    /// Whether each vertex is a convex corner (a reflex one never meets anything first).
    pub corners: &'a [bool],
}

/// How a point meets an outline: the gap, the normal from the outline to the point, the point
/// of the outline it meets, and the feature (an edge `k`, or `CORNER | m` for corner `m`).
#[derive(Clone, Copy, Debug)]
pub struct Meeting {
    /// Distance from the outline (negative inside it).
    pub gap: f64,
    /// Unit normal from the outline to the point.
    pub normal: DVec2,
    /// Where on the outline.
    pub at: DVec2,
    /// Which edge or corner.
    pub feature: u64,
}

/// One contact between two outlines.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PolygonContact {
    /// Contact point (mid-gap).
    pub point: DVec2,
    /// Unit normal pointing from `b` to `a`.
    pub normal: DVec2,
    /// Signed distance (negative: overlap).
    pub gap: f64,
    /// Which corner met which edge or corner (stable from step to step).
    pub feature: u64,
}

/// A meeting's feature bit for a corner (otherwise it is an edge).
pub const CORNER: u64 = 1 << 19;

impl Outline<'_> {
    fn len(&self) -> usize {
        self.points.len()
    }

    fn is_corner(&self, m: usize) -> bool {
        self.corners.is_empty() || self.corners[m]
    }

    /// Edge `k`: from vertex `k` to the next (a segment's two edges are its two faces).
    fn edge(&self, k: usize) -> (DVec2, DVec2) {
        (self.points[k], self.points[(k + 1) % self.len()])
    }

    /// Where `x` projects along edge `k`: 0 at its start, 1 at its end.
    fn along(&self, k: usize, x: DVec2) -> f64 {
        let (a, b) = self.edge(k);
        (x - a).dot(b - a) / (b - a).length_squared().max(f64::MIN_POSITIVE)
    }

    /// Edge `k`'s outward unit normal.
    fn outward(&self, k: usize) -> DVec2 {
        let (a, b) = self.edge(k);
        let e = b - a;
        DVec2::new(e.y, -e.x).normalize_or_zero()
    }

    /// Whether `x` lies inside (a segment has no inside).
    fn contains(&self, x: DVec2) -> bool {
        let n = self.len();
        n >= 3
            && (0..n).fold(false, |inside, k| {
                let (a, b) = self.edge(k);
                let crosses = (a.y > x.y) != (b.y > x.y) && x.x < a.x + (x.y - a.y) / (b.y - a.y) * (b.x - a.x);
                inside ^ crosses
            })
    }

    /// Whether `x` lies in corner `m`'s normal cone, beyond both its edges' ends by more than
    /// `band` (nearer, the edges meet it); with no band, on its boundary too (a disk's centre).
    fn in_cone(&self, m: usize, x: DVec2, band: f64) -> bool {
        let n = self.len();
        let v = self.points[m];
        let beyond = |w: DVec2| match (x - v).dot(w - v) {
            along if band > 0.0 => along < -band * w.distance(v),
            along => along <= 0.0,
        };
        beyond(self.points[(m + 1) % n]) && beyond(self.points[(m + n - 1) % n])
    }

    /// Every way a point `x` (a disk's centre) meets the outline within `alert`: inside it, the
    /// nearest edge and any other within `alert`; outside, each edge it faces and each corner in
    /// whose cone it lies.
    pub fn meetings(&self, x: DVec2, alert: f64, out: &mut Vec<Meeting>) {
        self.meet(x, alert, (None, 0.0), &|_| true, out)
    }

    /// [`Self::meetings`] of a corner `x` of another body, kept where that corner is the other
    /// body's support point against the normal (`supports(normal)`: its body lies on the normal's
    /// side there). Else its own edge meets this outline first, or, inside, another face of this
    /// body is the one it crossed: by the top face, a corner beside an arm's end would be pushed
    /// along the arm (and the arm's corner, by the same test, the other way). A segment is met
    /// from the side of `from` (the other body's centre) only, by that face.
    fn meet(
        &self,
        x: DVec2,
        alert: f64,
        (from, band): (Option<DVec2>, f64),
        supports: &dyn Fn(DVec2) -> bool,
        out: &mut Vec<Meeting>,
    ) {
        let n = self.len();
        let closest = |k: usize| {
            let (a, b) = self.edge(k);
            a + self.along(k, x).clamp(0.0, 1.0) * (b - a)
        };
        if self.contains(x) {
            // The face it crossed, and every other face it could leave by within the alert
            // distance: a body turning in the step may bring one of them nearer.
            let nearest = |edges: &mut dyn Iterator<Item = usize>| {
                edges.map(|k| (x.distance(closest(k)), k)).min_by(|p, q| p.0.total_cmp(&q.0))
            };
            // Only a supported face within the alert distance of the nearest can have been
            // crossed in the step. Else the nearest it is: a corner just inside a face it does
            // not support its body on would meet the grain's far side, millimetres deep.
            let any = nearest(&mut (0..n));
            let supported = nearest(&mut (0..n).filter(|&k| supports(self.outward(k))));
            let crossed = supported.filter(|s| any.is_some_and(|a| s.0 <= a.0 + alert)).or(any);
            for k in 0..n {
                let ((a, b), normal, t) = (self.edge(k), self.outward(k), self.along(k, x));
                // Signed: near a notch's inner corner, the notch's other side is still ahead.
                let gap = normal.dot(x - a);
                if crossed.is_some_and(|c| c.1 == k) {
                    out.push(Meeting { gap: -x.distance(closest(k)), normal, at: closest(k), feature: k as u64 });
                } else if gap >= 0.0 && gap <= alert && supports(normal) {
                    // A notch's wall runs on past its inner corner: a corner just inside the
                    // floor projects beyond the wall's end, and may slide into it.
                    let reach = |m: usize| if self.is_corner(m) { 0.0 } else { alert / a.distance(b) };
                    if t > -reach(k) && t < 1.0 + reach((k + 1) % n) {
                        out.push(Meeting { gap, normal, at: a + t * (b - a), feature: k as u64 });
                    }
                }
            }
            return;
        }
        // A segment's face towards `from`, the one a body on that side can meet.
        // A corner behind that face by less than the body's centre is in front of it has gone
        // through it (a fast grain's corner, pushed back); farther, it is simply on the other
        // side (a cup's arm beyond the divider standing in its notch).
        let face = from.filter(|_| n == 2).map(|c| {
            let front = self.outward(0).dot(c - self.points[0]);
            (usize::from(front < 0.0), front.abs())
        });
        for k in 0..n {
            let ((a, b), normal, t) = (self.edge(k), self.outward(k), self.along(k, x));
            let gap = normal.dot(x - a);
            // (Outside the body, yet behind the face's line by a rounding: beside its end.)
            let side = face.map_or(gap >= -band, |(f, front)| f == k && gap >= -front);
            // Past the ends by `band`: the corners of two blocks laid face to face coincide, to
            // roundings that grow as they move, and must go on meeting by their faces.
            let past = band / a.distance(b);
            let within = if band > 0.0 { (-past..=1.0 + past).contains(&t) } else { t > 0.0 && t < 1.0 };
            if within && side && gap <= alert && supports(normal) {
                out.push(Meeting { gap, normal, at: a + t * (b - a), feature: k as u64 });
            }
        }
        for m in (0..n).filter(|&m| self.is_corner(m) && self.in_cone(m, x, band)) {
            let v = self.points[m];
            let gap = x.distance(v);
            let normal = if gap > 0.0 { (x - v) / gap } else { self.corner_normal(m) };
            if gap <= alert && supports(normal) {
                out.push(Meeting { gap, normal, at: v, feature: CORNER | m as u64 });
            }
        }
    }

    /// Corner `m`'s own normal, between its two edges' (for a point exactly on it).
    fn corner_normal(&self, m: usize) -> DVec2 {
        let n = self.len();
        (self.outward(m) + self.outward((m + n - 1) % n)).normalize_or(DVec2::Y)
    }
}

/// Contacts between outlines `a` and `b` closer than `alert`, normals from `b` to `a`: the
/// corners of `a` against `b`, then those of `b` against `a` (a corner meeting a corner is
/// counted once, from `a`).
pub fn outline_outline(a: Outline, b: Outline, alert: f64, out: &mut Vec<PolygonContact>) {
    let mut meetings = Vec::new();
    let centroid = |o: Outline| o.points.iter().sum::<DVec2>() / o.len() as f64;
    // Corners this near an edge's end meet the edge (see `meet`).
    let band = 1e-3 * alert;
    let first = out.len();
    for (side, (mine, theirs)) in [(a, b), (b, a)].into_iter().enumerate() {
        let a_side = out.len();
        let (from, n) = (centroid(mine), mine.len());
        for i in (0..n).filter(|&i| mine.is_corner(i)) {
            let x = mine.points[i];
            let (prev, next) = (mine.points[(i + n - 1) % n], mine.points[(i + 1) % n]);
            // Corner i is its body's support point against `normal`, or will be within the step:
            // neither of its edges dips below it by more than the alert distance or a tenth of
            // the edge (a box lying tilted on a face keeps both corners' contacts; the alert
            // distance widened by a fast body's travel alone would let a far corner pass).
            let supports =
                |normal: DVec2| [prev, next].iter().all(|p| (*p - x).dot(normal) >= -alert.min(0.1 * p.distance(x)));
            meetings.clear();
            theirs.meet(x, alert, (Some(from), band), &supports, &mut meetings);
            for m in meetings.iter().filter(|m| side == 0 || m.feature & CORNER == 0) {
                // Normal from the outline met to the corner: from b to a when the corner is a's.
                let normal = if side == 0 { m.normal } else { -m.normal };
                let point = x - 0.5 * m.gap * m.normal;
                // A face on a face of the same length: each end is a's corner on b's face and
                // b's on a's, one contact twice (twins that make NLGS cycle); a's is kept.
                let twin = |c: &PolygonContact| c.point.distance(point) <= band && c.normal.dot(normal) > 1.0 - 1e-9;
                if side == 1 && out[first..a_side].iter().any(twin) {
                    continue;
                }
                let feature = (side as u64) << 62 | (i as u64) << 20 | m.feature;
                out.push(PolygonContact { point, normal, gap: m.gap, feature });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The outline of `points` with every vertex a corner (a convex polygon, a segment).
    fn outline(points: &[DVec2]) -> Outline<'_> {
        Outline { points, corners: &[] }
    }

    /// A cup: a 2 × 1 block with a notch 1.6 wide, 0.8 deep, cut from its top.
    fn cup() -> (Vec<DVec2>, Vec<bool>) {
        let p = [[-1., 0.], [1., 0.], [1., 1.], [0.8, 1.], [0.8, 0.2], [-0.8, 0.2], [-0.8, 1.], [-1., 1.]];
        let corners = vec![true, true, true, true, false, false, true, true];
        (p.iter().map(|v| DVec2::new(v[0], v[1])).collect(), corners)
    }

    #[test]
    fn a_point_in_a_notchs_corner_meets_both_sides_and_one_inside_the_face_it_crossed_and_the_wall_ahead() {
        let (points, corners) = cup();
        let cup = Outline { points: &points, corners: &corners };
        let mut out = Vec::new();
        // Near the notch's lower right corner: the floor (edge 4) and the right side (edge 3).
        cup.meetings(DVec2::new(0.75, 0.26), 0.1, &mut out);
        let mut found: Vec<(u64, f64)> = out.iter().map(|m| (m.feature, m.gap)).collect();
        found.sort_by_key(|f| f.0);
        assert_eq!(found.len(), 2, "{out:?}");
        assert!(found[0].0 == 3 && (found[0].1 - 0.05).abs() < 1e-12, "{found:?}");
        assert!(found[1].0 == 4 && (found[1].1 - 0.06).abs() < 1e-12, "{found:?}");
        let right = out.iter().find(|m| m.feature == 3).unwrap();
        assert!((right.normal - DVec2::new(-1.0, 0.0)).length() < 1e-12);
        // Inside the right post, nearer its outer side: that side alone, at a negative gap.
        out.clear();
        cup.meetings(DVec2::new(0.97, 0.5), 0.1, &mut out);
        assert_eq!(out.len(), 1, "{out:?}");
        assert!(
            out[0].feature == 1 && (out[0].gap + 0.03).abs() < 1e-12 && (out[0].normal - DVec2::X).length() < 1e-12
        );
        // Beyond the rim's outer corner: the corner, along the diagonal.
        out.clear();
        cup.meetings(DVec2::new(1.03, 1.04), 0.1, &mut out);
        assert_eq!(out.len(), 1, "{out:?}");
        assert!(out[0].feature == CORNER | 2 && (out[0].gap - 0.05).abs() < 1e-12, "{out:?}");
        // Just under the notch's floor beside its inner corner (projecting past the wall's end):
        // the floor it crossed, and the wall 0.01 ahead, which it would slide into.
        out.clear();
        cup.meetings(DVec2::new(0.79, 0.1999), 0.05, &mut out);
        let mut found: Vec<(u64, f64)> = out.iter().map(|m| (m.feature, m.gap)).collect();
        found.sort_by_key(|f| f.0);
        assert_eq!(found.len(), 2, "{out:?}");
        assert!(found[0].0 == 3 && (found[0].1 - 0.01).abs() < 1e-12, "{found:?}");
        assert!(found[1].0 == 4 && (found[1].1 + 1e-4).abs() < 1e-12, "{found:?}");
        // Far away: nothing.
        out.clear();
        cup.meetings(DVec2::new(0.0, 0.6), 0.1, &mut out);
        assert!(out.is_empty(), "{out:?}");
    }

    #[test]
    fn a_box_in_a_cup_touches_its_floor_by_its_two_corners_and_a_corner_meets_a_corner_once() {
        let (points, corners) = cup();
        let cup = Outline { points: &points, corners: &corners };
        let h = 0.01;
        let block: Vec<DVec2> =
            [[-0.5, 0.2 + h], [0.5, 0.2 + h], [0.5, 0.7], [-0.5, 0.7]].iter().map(|v| DVec2::new(v[0], v[1])).collect();
        let mut out = Vec::new();
        outline_outline(outline(&block), cup, 0.05, &mut out);
        assert_eq!(out.len(), 2, "{out:?}");
        for c in &out {
            assert!((c.gap - h).abs() < 1e-12 && (c.normal - DVec2::Y).length() < 1e-12, "{c:?}");
        }
        // Two squares corner to corner along the diagonal: one contact, along it.
        let sq = |c: DVec2| {
            [c + DVec2::new(-1., -1.), c + DVec2::new(1., -1.), c + DVec2::new(1., 1.), c + DVec2::new(-1., 1.)]
        };
        let (lower, upper) = (sq(DVec2::ZERO), sq(DVec2::splat(2.0 + 0.01)));
        out.clear();
        outline_outline(outline(&upper), outline(&lower), 0.1, &mut out);
        assert_eq!(out.len(), 1, "{out:?}");
        assert!(
            (out[0].gap - 0.01 * 2f64.sqrt()).abs() < 1e-12
                && (out[0].normal - DVec2::ONE.normalize()).length() < 1e-12
        );
    }

    /// A cup standing over a divider whose end is in its notch: one arm on each side of it, and
    /// no contact (the arm beyond it has not gone through it).
    #[test]
    fn a_cup_straddling_a_divider_does_not_touch_it() {
        let (points, corners) = cup();
        let divider = [DVec2::new(0.3, 0.5), DVec2::new(0.3, 3.0)];
        let mut out = Vec::new();
        outline_outline(Outline { points: &points, corners: &corners }, outline(&divider), 0.05, &mut out);
        assert!(out.is_empty(), "{out:?}");
        // Lowered until its end is 0.01 above the notch's floor: the end meets the floor.
        let divider = [DVec2::new(0.3, 0.21), DVec2::new(0.3, 3.0)];
        outline_outline(Outline { points: &points, corners: &corners }, outline(&divider), 0.05, &mut out);
        assert_eq!(out.len(), 1, "{out:?}");
        assert!((out[0].gap - 0.01).abs() < 1e-12 && (out[0].normal - DVec2::NEG_Y).length() < 1e-12, "{out:?}");
    }

    /// Two unit squares laid side by side, their corners coincident to roundings (1e-12 off,
    /// either way): they meet by their shared side at both ends, once each, the normal along x.
    #[test]
    fn blocks_laid_face_to_face_meet_by_the_joint_at_both_ends_once() {
        let sq = |c: DVec2| {
            [c + DVec2::new(-0.5, -0.5), c + DVec2::new(0.5, -0.5), c + DVec2::new(0.5, 0.5), c + DVec2::new(-0.5, 0.5)]
        };
        for offset in [DVec2::ZERO, DVec2::new(1e-12, 1e-12), DVec2::new(-1e-12, 1e-12), DVec2::new(1e-12, -1e-12)] {
            let (left, right) = (sq(DVec2::new(0.5, 0.5)), sq(DVec2::new(1.5, 0.5) + offset));
            let mut out = Vec::new();
            outline_outline(outline(&right), outline(&left), 0.05, &mut out);
            let mut ys: Vec<f64> = out.iter().map(|c| c.point.y).collect();
            ys.sort_by(f64::total_cmp);
            assert!(ys.len() == 2 && ys[0].abs() < 1e-9 && (ys[1] - 1.0).abs() < 1e-9, "{offset}: {out:?}");
            assert!(out.iter().all(|c| (c.normal - DVec2::X).length() < 1e-9 && c.gap.abs() < 1e-11), "{out:?}");
        }
    }

    /// A box tilted by 0.3 rad over a segment: its lowest corner is the deepest contact, at its
    /// height, the normal straight up.
    #[test]
    fn a_tilted_box_on_a_segment_touches_with_its_lowest_corner() {
        let rot = DVec2::from_angle(0.3);
        let b: Vec<DVec2> = [[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]]
            .iter()
            .map(|v| DVec2::new(0.0, 1.0) + rot.rotate(DVec2::new(v[0], v[1])))
            .collect();
        let low = b.iter().map(|v| v.y).fold(f64::INFINITY, f64::min);
        let seg = [DVec2::new(-5.0, 0.0), DVec2::new(5.0, 0.0)];
        let mut out = Vec::new();
        outline_outline(outline(&b), outline(&seg), 1.0, &mut out);
        let deepest = out.iter().map(|c| c.gap).fold(f64::INFINITY, f64::min);
        assert!((deepest - low).abs() < 1e-12, "{out:?}");
        assert!(out.iter().all(|c| (c.normal - DVec2::Y).length() < 1e-12), "{out:?}");
    }

    /// Two squares side by side, their tops nearly flush, overlapping by 1e-5 sideways: each
    /// corner inside the other square is nearer its top (1e-7) than its side, yet meets the
    /// side, so every contact pushes them apart sideways. Meeting the nearest edge, the two
    /// corners would be pushed up and down against each other: a pair of opposite contacts
    /// holding any force (a 184 N self-stress in a 168 N pile of crosses, before).
    #[test]
    fn squares_side_by_side_with_flush_tops_meet_by_their_sides_only() {
        let sq = |c: DVec2| {
            [c + DVec2::new(-0.5, -0.5), c + DVec2::new(0.5, -0.5), c + DVec2::new(0.5, 0.5), c + DVec2::new(-0.5, 0.5)]
        };
        let (left, right) = (sq(DVec2::ZERO), sq(DVec2::new(1.0 - 1e-5, -1e-7)));
        let mut out = Vec::new();
        outline_outline(outline(&right), outline(&left), 0.05, &mut out);
        assert!(out.len() >= 2, "{out:?}");
        for c in &out {
            assert!((c.normal - DVec2::X).length() < 1e-9 && (c.gap + 1e-5).abs() < 1e-12, "{c:?}");
        }
    }

    /// A corner just inside a square's top (1e-5), near its right end, of a body tilted 10°
    /// whose next corner dips below the top beyond that end: the top face is not the one this
    /// corner supports its body on, and the right face, which it would support, is 0.1 away.
    /// It meets the top at its own depth, not the far side 0.1 deep (a hexagon's corner met so
    /// kicked the pile's grains by 0.27 rad in the position projection).
    #[test]
    fn a_corner_just_inside_a_face_its_body_does_not_rest_on_does_not_meet_the_far_side() {
        let square = [DVec2::ZERO, DVec2::X, DVec2::ONE, DVec2::Y];
        let (tilt, side) = (10f64.to_radians(), 0.4);
        let (d1, d2) = (DVec2::from_angle(-tilt), DVec2::from_angle(-tilt).perp());
        let x = DVec2::new(0.9, 1.0 - 1e-5);
        let tilted = [x, x + side * d1, x + side * (d1 + d2), x + side * d2];
        let mut out = Vec::new();
        outline_outline(outline(&tilted), outline(&square), 0.01, &mut out);
        let corner = |c: &&PolygonContact| c.feature >> 62 == 0 && (c.feature >> 20) & 0xff == 0;
        let mine: Vec<&PolygonContact> = out.iter().filter(corner).collect();
        assert_eq!(mine.len(), 1, "{out:?}");
        assert!(mine[0].feature & 0xff == 2 && (mine[0].gap + 1e-5).abs() < 1e-12, "{mine:?}");
        assert!((mine[0].normal - DVec2::Y).length() < 1e-12, "{mine:?}");
        // The square's corner inside the tilted body meets it too, at its true depth.
        assert!(out.iter().all(|c| c.gap > -0.02), "{out:?}");
    }
}
