//! Polygon–polygon (and polygon–segment) contacts in f64 by the separating-axis test and
//! reference-face clipping (as Box2D's `b2CollidePolygons`). Exact for touching faces, where a
//! GJK/EPA pair query is degenerate: two boxes side by side with zero gap must give a zero gap
//! on the shared face, not an overlap along the other axis.

use glam::DVec2;

/// Outward unit normal of edge `k` of a counter-clockwise polygon (a 2-vertex "polygon" is a
/// two-sided segment).
fn edge_normal(p: &[DVec2], k: usize) -> DVec2 {
    let e = p[(k + 1) % p.len()] - p[k];
    DVec2::new(e.y, -e.x).normalize_or_zero()
}

/// Largest separation of `b` from the edges of `a`, and the edge that achieves it.
fn max_separation(a: &[DVec2], b: &[DVec2]) -> (f64, usize) {
    let mut best = (f64::NEG_INFINITY, 0);
    for k in 0..a.len() {
        let n = edge_normal(a, k);
        let s = b.iter().map(|v| n.dot(*v - a[k])).fold(f64::INFINITY, f64::min);
        if s > best.0 {
            best = (s, k);
        }
    }
    best
}

/// One contact point of a manifold.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClipPoint {
    /// Contact point.
    pub point: DVec2,
    /// Unit normal pointing from `b` to `a`.
    pub normal: DVec2,
    /// Signed distance (negative: overlap).
    pub gap: f64,
    /// Which features met (stable from step to step).
    pub feature: u64,
}

/// Up to two contacts between convex counter-clockwise polygons `a` and `b` (world coordinates)
/// closer than `alert`.
pub fn polygon_polygon(a: &[DVec2], b: &[DVec2], alert: f64, out: &mut Vec<ClipPoint>) {
    let (sep_a, edge_a) = max_separation(a, b);
    if sep_a > alert {
        return;
    }
    let (sep_b, edge_b) = max_separation(b, a);
    if sep_b > alert {
        return;
    }
    // Prefer `a`'s face unless `b`'s is clearly better, so the choice does not flicker.
    let size = a.iter().chain(b).map(|v| v.length_squared()).fold(0.0, f64::max).sqrt().max(1e-300);
    let flip = sep_b > sep_a + 1e-9 * size;
    let (reference, incident, edge) = if flip { (b, a, edge_b) } else { (a, b, edge_a) };
    let n = edge_normal(reference, edge);
    // Incident edge: the one most anti-parallel to the reference normal.
    let inc = (0..incident.len())
        .min_by(|&i, &j| edge_normal(incident, i).dot(n).total_cmp(&edge_normal(incident, j).dot(n)))
        .unwrap_or(0);
    let (v1, v2) = (reference[edge], reference[(edge + 1) % reference.len()]);
    let mut seg = [incident[inc], incident[(inc + 1) % incident.len()]];
    let t = (v2 - v1).normalize_or_zero();
    // Clip the incident edge to the reference edge's side planes.
    for (dir, offset) in [(-t, -t.dot(v1)), (t, t.dot(v2))] {
        let d0 = dir.dot(seg[0]) - offset;
        let d1 = dir.dot(seg[1]) - offset;
        if d0 > 0.0 && d1 > 0.0 {
            return;
        }
        if d0 > 0.0 {
            seg[0] = seg[0] + (seg[1] - seg[0]) * (d0 / (d0 - d1));
        } else if d1 > 0.0 {
            seg[1] = seg[1] + (seg[0] - seg[1]) * (d1 / (d1 - d0));
        }
    }
    // Normal from b to a: the reference normal points out of the reference polygon.
    let normal = if flip { n } else { -n };
    for (k, p) in seg.iter().enumerate() {
        let gap = n.dot(*p - v1);
        if gap <= alert {
            let feature = ((flip as u64) << 62) | ((edge as u64) << 40) | ((inc as u64) << 20) | k as u64;
            out.push(ClipPoint { point: *p - 0.5 * gap * n, normal, gap, feature });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(c: DVec2, h: f64) -> Vec<DVec2> {
        vec![c + DVec2::new(-h, -h), c + DVec2::new(h, -h), c + DVec2::new(h, h), c + DVec2::new(-h, h)]
    }

    #[test]
    fn boxes_side_by_side_touch_on_their_shared_face() {
        let mut out = Vec::new();
        polygon_polygon(&square(DVec2::new(0.5, 0.5), 0.5), &square(DVec2::new(1.5, 0.5), 0.5), 0.01, &mut out);
        assert_eq!(out.len(), 2, "{out:?}");
        for c in &out {
            assert!(c.gap.abs() < 1e-15 && (c.normal - DVec2::new(-1.0, 0.0)).length() < 1e-15, "{c:?}");
            assert!((c.point.x - 1.0).abs() < 1e-15);
        }
    }

    #[test]
    fn a_tilted_box_on_a_segment_touches_with_its_lowest_corner() {
        let rot = DVec2::from_angle(0.3);
        let b: Vec<DVec2> = square(DVec2::ZERO, 0.5).iter().map(|v| DVec2::new(0.0, 1.0) + rot.rotate(*v)).collect();
        let low = b.iter().map(|v| v.y).fold(f64::INFINITY, f64::min);
        let seg = [DVec2::new(-5.0, 0.0), DVec2::new(5.0, 0.0)];
        let mut out = Vec::new();
        polygon_polygon(&b, &seg, 1.0, &mut out);
        let deepest = out.iter().map(|c| c.gap).fold(f64::INFINITY, f64::min);
        assert!((deepest - low).abs() < 1e-12, "{out:?}");
        assert!(out.iter().all(|c| (c.normal - DVec2::Y).length() < 1e-12));
    }
}
