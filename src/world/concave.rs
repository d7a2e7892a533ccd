//! Concave polygons: an outline that does not cross itself, checked and oriented here. Mass,
//! drawing, outputs and contacts all read the outline itself (the narrow phase meets its convex
//! corners and its edges: `detection::outline`).

use glam::DVec2;

/// The most vertices a concave outline may have (a convex polygon may have more).
pub const MAX_CONCAVE_VERTICES: usize = 256;

/// Twice the signed area of triangle `a b c` (positive counter-clockwise).
fn orient(a: DVec2, b: DVec2, c: DVec2) -> f64 {
    (b - a).perp_dot(c - a)
}

/// The outline `vertices` (either orientation) made counter-clockwise, with repeated vertices and
/// vertices on a straight edge dropped; refuses an outline that crosses or touches itself.
pub fn simple_outline(vertices: &[DVec2]) -> Result<Vec<DVec2>, String> {
    if vertices.len() > MAX_CONCAVE_VERTICES {
        return Err(format!(
            "a concave polygon has at most {MAX_CONCAVE_VERTICES} vertices, got {} (a convex one may have more)",
            vertices.len()
        ));
    }
    let size = vertices.iter().map(|v| (*v - vertices[0]).length()).fold(0.0, f64::max);
    let eps = 1e-12 * size * size;
    // Indices kept, so that errors name the vertices as given.
    let mut kept: Vec<usize> = (0..vertices.len()).collect();
    kept.dedup_by(|b, a| vertices[*a] == vertices[*b]);
    while kept.len() > 1 && vertices[kept[0]] == vertices[*kept.last().unwrap()] {
        kept.pop();
    }
    loop {
        let n = kept.len();
        if n < 3 {
            return Err("degenerate polygon: fewer than 3 distinct vertices off one line".into());
        }
        // Vertex k with the ones before and after it.
        let corner = |k: usize| (vertices[kept[(k + n - 1) % n]], vertices[kept[k]], vertices[kept[(k + 1) % n]]);
        let straight = (0..n).find(|&k| {
            let (a, b, c) = corner(k);
            orient(a, b, c).abs() <= eps
        });
        let Some(k) = straight else { break };
        let (a, b, c) = corner(k);
        if (b - a).dot(c - b) < 0.0 {
            return Err(format!("polygon folds back on itself at vertex {}", kept[k]));
        }
        kept.remove(k);
    }
    let n = kept.len();
    let at = |k: usize| vertices[kept[k % n]];
    for e in 0..n {
        for f in e + 2..n {
            if e == 0 && f == n - 1 {
                continue;
            }
            if segments_meet(at(e), at(e + 1), at(f), at(f + 1), eps) {
                return Err(format!(
                    "polygon's edges cross or touch: the edge from vertex {} and the one from vertex {}",
                    kept[e], kept[f]
                ));
            }
        }
    }
    let area2: f64 = (0..n).map(|k| at(k).perp_dot(at(k + 1))).sum();
    let mut outline: Vec<DVec2> = (0..n).map(at).collect();
    if area2 < 0.0 {
        outline.reverse();
    }
    Ok(outline)
}

/// Whether segments `a b` and `c d` share a point (touching included).
fn segments_meet(a: DVec2, b: DVec2, c: DVec2, d: DVec2, eps: f64) -> bool {
    let (d1, d2) = (orient(a, b, c), orient(a, b, d));
    let (d3, d4) = (orient(c, d, a), orient(c, d, b));
    let straddles = |p: f64, q: f64| (p > eps && q < -eps) || (p < -eps && q > eps);
    if straddles(d1, d2) && straddles(d3, d4) {
        return true;
    }
    let on = |p: DVec2, q: DVec2, x: DVec2, o: f64| {
        o.abs() <= eps && x.x >= p.x.min(q.x) && x.x <= p.x.max(q.x) && x.y >= p.y.min(q.y) && x.y <= p.y.max(q.y)
    };
    on(a, b, c, d1) || on(a, b, d, d2) || on(c, d, a, d3) || on(c, d, b, d4)
}

/// Which vertices of a counter-clockwise outline are convex corners (the others are reflex: the
/// inner corners of its notches, which nothing outside meets first).
pub fn convex_corners(outline: &[DVec2]) -> Vec<bool> {
    let n = outline.len();
    (0..n).map(|k| orient(outline[(k + n - 1) % n], outline[k], outline[(k + 1) % n]) > 0.0).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area(p: &[DVec2]) -> f64 {
        (0..p.len()).map(|k| p[k].perp_dot(p[(k + 1) % p.len()])).sum::<f64>() / 2.0
    }

    fn points(xy: &[[f64; 2]]) -> Vec<DVec2> {
        xy.iter().map(|p| DVec2::new(p[0], p[1])).collect()
    }

    #[test]
    fn outlines_come_out_counter_clockwise_with_their_reflex_corners_found() {
        let l = points(&[[0., 0.], [3., 0.], [3., 1.], [1., 1.], [1., 3.], [0., 3.]]);
        let mut clockwise = l.clone();
        clockwise.reverse();
        for given in [&l, &clockwise] {
            let outline = simple_outline(given).unwrap();
            assert!((area(&outline) - 5.0).abs() < 1e-12, "{outline:?}");
            let reflex: Vec<DVec2> =
                convex_corners(&outline).iter().zip(&outline).filter(|(c, _)| !**c).map(|(_, v)| *v).collect();
            assert_eq!(reflex, vec![DVec2::new(1.0, 1.0)]);
        }
        // A square with a vertex in the middle of an edge and one repeated: four corners.
        let square = simple_outline(&points(&[[0., 0.], [1., 0.], [2., 0.], [2., 2.], [0., 2.], [0., 2.]])).unwrap();
        assert_eq!(square.len(), 4);
        assert!(convex_corners(&square).iter().all(|c| *c));
    }

    #[test]
    fn outlines_that_cross_touch_or_fold_back_are_refused_naming_vertices() {
        let bowtie = simple_outline(&points(&[[0., 0.], [1., 1.], [1., 0.], [0., 1.]])).unwrap_err();
        assert!(
            bowtie.contains("cross or touch") && bowtie.contains("vertex 0") && bowtie.contains("vertex 2"),
            "{bowtie}"
        );
        // Two loops meeting at one point.
        let pinched =
            simple_outline(&points(&[[0., 0.], [1., 0.], [1., 1.], [2., 1.], [2., 2.], [1., 2.], [1., 1.], [0., 1.]]))
                .unwrap_err();
        assert!(pinched.contains("cross or touch"), "{pinched}");
        let spike = simple_outline(&points(&[[0., 0.], [2., 0.], [1., 0.], [1., 1.]])).unwrap_err();
        assert!(spike.contains("folds back") && spike.contains("vertex 1"), "{spike}");
        let many: Vec<DVec2> = (0..300).map(|k| DVec2::from_angle(k as f64 * 0.02) * (1.0 + (k % 2) as f64)).collect();
        assert!(simple_outline(&many).unwrap_err().contains("at most 256"));
    }
}
