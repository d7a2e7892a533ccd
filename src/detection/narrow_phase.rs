//! Exact narrow phase, in f64: disk–disk, disk–segment and disk–polygon closed-form (a clump's
//! disks each as a disk, a contact per pair of disks that touch; a concave polygon's outline met
//! edge by edge), polygon–polygon and polygon–segment by their outlines' corners and edges
//! ([`super::outline`]). Disk–polygon is not parry2d's f32 query: its normals, 1e-7 rad off,
//! tilted a clump's two supports on one face against each other, and NLGS cycled.

use glam::DVec2;

use super::outline::{outline_outline, Outline};
use super::{Antagonist, Configuration, DetectedContact};
use crate::world::{Bodies, BodyShape, PolygonShape, Wall, WallShape};

/// Gap, normal (from `b` to `a`) and mid-gap point of two disks.
#[inline]
pub fn disk_disk(xa: DVec2, ra: f64, xb: DVec2, rb: f64) -> (f64, DVec2, DVec2) {
    let d = xa - xb;
    let dist = d.length();
    let n = if dist > 0.0 { d / dist } else { DVec2::Y };
    let gap = dist - ra - rb;
    (gap, n, xb + n * (rb + 0.5 * gap))
}

/// Gap, normal (from the segment to the disk) and mid-gap point of a disk and a segment.
#[inline]
pub fn disk_segment(x: DVec2, r: f64, a: DVec2, b: DVec2) -> (f64, DVec2, DVec2) {
    let ab = b - a;
    let s = ((x - a).dot(ab) / ab.length_squared().max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
    let c = a + s * ab;
    let d = x - c;
    let dist = d.length();
    // A centre exactly on the segment: push along the segment's left normal.
    let n = if dist > 0.0 { d / dist } else { ab.perp().normalize_or(DVec2::Y) };
    let gap = dist - r;
    (gap, n, c + n * (0.5 * gap))
}

/// Contact of a disk (centre `x`, radius `r`) with a convex polygon (counter-clockwise
/// vertices `local` in its frame) posed at `xp`, angle `ap`, in f64, relative to the disk so that
/// precision follows grain size: the nearest edge outside, the least deep face inside. Returns
/// (mid-gap point, normal from the polygon to the disk, gap) when the gap is within `alert`.
fn disk_polygon(x: DVec2, r: f64, local: &[DVec2], xp: DVec2, ap: f64, alert: f64) -> Option<(DVec2, DVec2, f64)> {
    let rot = DVec2::from_angle(ap);
    let vertex = |k: usize| xp - x + rot.rotate(local[k % local.len()]);
    // The face the centre lies farthest outside of (least deep inside, when inside them all).
    let (mut depth, mut face) = (f64::NEG_INFINITY, DVec2::Y);
    for k in 0..local.len() {
        let (a, b) = (vertex(k), vertex(k + 1));
        let outward = (b - a).perp().normalize_or_zero() * -1.0;
        let s = -a.dot(outward);
        if s > depth {
            (depth, face) = (s, outward);
        }
    }
    let (gap, normal, point) = if depth <= 0.0 {
        (depth - r, face, x - face * (0.5 * (depth + r)))
    } else {
        (0..local.len())
            .map(|k| disk_segment(DVec2::ZERO, r, vertex(k), vertex(k + 1)))
            .min_by(|p, q| p.0.total_cmp(&q.0))
            .map(|(gap, n, point)| (gap, n, x + point))?
    };
    (gap <= alert).then_some((point, normal, gap))
}

/// Every contact of a disk (centre `x`, radius `r`) with a polygon posed at `pose` (position,
/// angle), passed to `emit` as (feature, mid-gap point, normal from the polygon to the disk, gap):
/// a convex polygon's one ([`disk_polygon`], feature 0), or each that a concave one's outline
/// (`outline`, in the world frame) makes, by edge or corner.
fn disk_against(
    x: DVec2,
    r: f64,
    polygon: &PolygonShape,
    outline: Option<&[DVec2]>,
    (xp, ap): (DVec2, f64),
    alert: f64,
    mut emit: impl FnMut(usize, DVec2, DVec2, f64),
) {
    let Some(points) = outline else {
        if let Some((point, normal, gap)) = disk_polygon(x, r, &polygon.vertices, xp, ap, alert) {
            emit(0, point, normal, gap);
        }
        return;
    };
    let mut meetings = Vec::new();
    Outline { points, corners: &polygon.corners }.meetings(x, alert + r, &mut meetings);
    for m in meetings {
        let gap = m.gap - r;
        emit(m.feature as usize, m.at + 0.5 * gap * m.normal, m.normal, gap);
    }
}

/// Contacts between bodies `i < j`, body `j` taken at its position plus `image` (a periodic
/// image; zero for a direct pair).
pub fn body_body(
    bodies: &Bodies,
    config: &Configuration,
    (i, j, image): (usize, usize, DVec2),
    alert: f64,
    out: &mut Vec<DetectedContact>,
) {
    let (xi, xj) = (config.position[i], config.position[j] + image);
    let push = |out: &mut Vec<DetectedContact>, feature: u64, point: DVec2, normal: DVec2, gap: f64| {
        out.push(DetectedContact { i, other: Antagonist::Body(j), feature, point, normal, gap, image })
    };
    match (bodies.shape[i], bodies.shape[j]) {
        (BodyShape::Disk { radius: ri }, BodyShape::Disk { radius: rj }) => {
            let (gap, normal, point) = disk_disk(xi, ri, xj, rj);
            if gap <= alert {
                push(out, 0, point, normal, gap);
            }
        }
        _ if bodies.inv_mass[i] == 0.0 && bodies.inv_mass[j] == 0.0 => {}
        (BodyShape::Polygon(p), BodyShape::Polygon(q)) => {
            let mut pts = Vec::new();
            let b: Vec<DVec2> = world_vertices(bodies, config, j).into_iter().map(|v| v + image).collect();
            let a = world_vertices(bodies, config, i);
            let (p, q) = (&bodies.polygons[p as usize], &bodies.polygons[q as usize]);
            let (a, b) = (Outline { points: &a, corners: &p.corners }, Outline { points: &b, corners: &q.corners });
            outline_outline(a, b, alert, &mut pts);
            for c in pts {
                push(out, c.feature, c.point, c.normal, c.gap);
            }
        }
        (BodyShape::Polygon(p), _) => {
            let polygon = &bodies.polygons[p as usize];
            let outline = polygon.is_concave().then(|| world_vertices(bodies, config, i));
            for (b, (x, radius)) in round_pieces(bodies, config, j, image).enumerate() {
                disk_against(
                    x,
                    radius,
                    polygon,
                    outline.as_deref(),
                    (xi, config.angle_of(i)),
                    alert,
                    |f, point, n, gap| push(out, piece_pair(f, b), point, -n, gap),
                );
            }
        }
        (_, BodyShape::Polygon(p)) => {
            let polygon = &bodies.polygons[p as usize];
            let outline = polygon.is_concave().then(|| world_vertices(bodies, config, j));
            let outline: Option<Vec<DVec2>> = outline.map(|o| o.into_iter().map(|v| v + image).collect());
            for (a, (x, radius)) in round_pieces(bodies, config, i, DVec2::ZERO).enumerate() {
                disk_against(
                    x,
                    radius,
                    polygon,
                    outline.as_deref(),
                    (xj, config.angle_of(j)),
                    alert,
                    |f, point, n, gap| push(out, piece_pair(a, f), point, n, gap),
                );
            }
        }
        // Disks and clumps: every disk of one against every disk of the other.
        (_, _) => {
            let theirs = round_pieces(bodies, config, j, image);
            for (a, (xa, ra)) in round_pieces(bodies, config, i, DVec2::ZERO).enumerate() {
                for (b, (xb, rb)) in theirs.clone().enumerate() {
                    let (gap, normal, point) = disk_disk(xa, ra, xb, rb);
                    if gap <= alert {
                        push(out, piece_pair(a, b), point, normal, gap);
                    }
                }
            }
        }
    }
}

/// A disk's or a clump's disks in the world frame, body `k` shifted by `image` (none for a
/// polygon), without allocating: the narrow phase calls this for every candidate pair.
fn round_pieces<'a>(
    bodies: &'a Bodies,
    config: &Configuration,
    k: usize,
    image: DVec2,
) -> impl Iterator<Item = (DVec2, f64)> + Clone + 'a {
    let x = config.position[k] + image;
    let own = match bodies.shape[k] {
        BodyShape::Disk { radius } => Some((x, radius)),
        _ => None,
    };
    let clump = match bodies.shape[k] {
        BodyShape::Clump(c) => Some(bodies.clump_disks(c, x, config.angle_of(k))),
        _ => None,
    };
    own.into_iter().chain(clump.into_iter().flatten())
}

/// The feature of a contact between disk `a` of body `i` and disk `b` of its antagonist (0 for
/// a body that is one disk): a clump pair's contacts stay apart from step to step.
fn piece_pair(a: usize, b: usize) -> u64 {
    (a as u64) << 32 | b as u64
}

fn world_vertices(bodies: &Bodies, config: &Configuration, k: usize) -> Vec<DVec2> {
    let BodyShape::Polygon(p) = bodies.shape[k] else { return Vec::new() };
    let rot = DVec2::from_angle(config.angle_of(k));
    bodies.polygons[p as usize].vertices.iter().map(|v| config.position[k] + rot.rotate(*v)).collect()
}

/// Contacts between body `k` and wall `w`.
pub fn body_wall(
    bodies: &Bodies,
    config: &Configuration,
    k: usize,
    w: usize,
    wall: &Wall,
    alert: f64,
    out: &mut Vec<DetectedContact>,
) {
    let x = config.position[k];
    let push = |out: &mut Vec<DetectedContact>, feature: u64, point: DVec2, normal: DVec2, gap: f64| {
        out.push(DetectedContact { i: k, other: Antagonist::Wall(w), feature, point, normal, gap, image: DVec2::ZERO })
    };
    // One disk (a clump's disk `a`) against the wall.
    let round = |out: &mut Vec<DetectedContact>, a: usize, x: DVec2, radius: f64| match &wall.shape {
        WallShape::Segment { .. } => {
            let p = wall.world_points();
            let (gap, normal, point) = disk_segment(x, radius, p[0], p[1]);
            if gap <= alert {
                push(out, a as u64, point, normal, gap);
            }
        }
        WallShape::Polygon(poly) => {
            let outline = poly.is_concave().then(|| wall.world_points());
            disk_against(x, radius, poly, outline.as_deref(), (wall.center, wall.angle), alert, |f, point, n, gap| {
                push(out, a as u64 | (f as u64) << 32, point, n, gap)
            });
        }
    };
    match (bodies.shape[k], &wall.shape) {
        (BodyShape::Disk { radius }, _) => round(out, 0, x, radius),
        (BodyShape::Clump(c), _) => {
            for (a, (x, radius)) in bodies.clump_disks(c, x, config.angle_of(k)).enumerate() {
                round(out, a, x, radius);
            }
        }
        (BodyShape::Polygon(p), shape) => {
            let mut pts = Vec::new();
            let (a, b) = (world_vertices(bodies, config, k), wall.world_points());
            let polygon = &bodies.polygons[p as usize];
            let theirs: &[bool] = match shape {
                WallShape::Polygon(poly) => &poly.corners,
                WallShape::Segment { .. } => &[],
            };
            let (a, b) = (Outline { points: &a, corners: &polygon.corners }, Outline { points: &b, corners: theirs });
            outline_outline(a, b, alert, &mut pts);
            for c in pts {
                push(out, c.feature, c.point, c.normal, c.gap);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::BodySpec;

    #[test]
    fn disk_pairs_have_exact_gaps_and_normals_from_j_to_i() {
        let (gap, n, p) = disk_disk(DVec2::new(0.0, 2.0), 1.0, DVec2::ZERO, 0.5);
        assert!((gap - 0.5).abs() < 1e-15 && (n - DVec2::Y).length() < 1e-15);
        assert!((p - DVec2::new(0.0, 0.75)).length() < 1e-15);
        let (gap, n, _) = disk_segment(DVec2::new(3.0, 0.9), 1.0, DVec2::new(-1.0, 0.0), DVec2::new(1.0, 0.0));
        assert!((gap - ((2.0f64).hypot(0.9) - 1.0)).abs() < 1e-14 && n.x > 0.0 && n.y > 0.0);
    }

    #[test]
    fn disk_polygon_is_exact_outside_a_face_at_a_corner_and_inside() {
        let square = [DVec2::new(-1.0, -1.0), DVec2::new(1.0, -1.0), DVec2::new(1.0, 1.0), DVec2::new(-1.0, 1.0)];
        let (xp, ap) = (DVec2::new(1e4, 5.0), std::f64::consts::FRAC_PI_2);
        // Above the top face (the square turned a quarter: still a square), 0.25 away.
        let (p, n, gap) = disk_polygon(xp + DVec2::new(0.3, 1.5), 0.25, &square, xp, ap, 1.0).unwrap();
        assert!((gap - 0.25).abs() < 1e-12 && (n - DVec2::Y).length() < 1e-12, "{gap} {n}");
        assert!((p - (xp + DVec2::new(0.3, 1.125))).length() < 1e-9, "{p}");
        // Beyond a corner: the normal points from the corner.
        let (_, n, gap) = disk_polygon(xp + DVec2::new(2.0, 2.0), 0.5, &square, xp, ap, 1.0).unwrap();
        assert!((gap - (2f64.sqrt() - 0.5)).abs() < 1e-12 && (n - DVec2::ONE.normalize()).length() < 1e-12);
        // Centre inside, nearest the right face: pushed out along +x.
        let (p, n, gap) = disk_polygon(xp + DVec2::new(0.9, 0.2), 0.5, &square, xp, ap, 1.0).unwrap();
        assert!((gap + 0.6).abs() < 1e-12 && (n - DVec2::X).length() < 1e-12, "{gap} {n}");
        assert!((p - (xp + DVec2::new(0.7, 0.2))).length() < 1e-9, "{p}");
        assert!(disk_polygon(xp + DVec2::new(0.0, 3.0), 0.5, &square, xp, ap, 0.1).is_none());
    }

    #[test]
    fn a_square_resting_on_a_segment_gets_two_contacts_pointing_up() {
        let mut bodies = Bodies::new(true);
        let sq = vec![DVec2::new(-0.5, -0.5), DVec2::new(0.5, -0.5), DVec2::new(0.5, 0.5), DVec2::new(-0.5, 0.5)];
        bodies.add(&BodySpec::polygon(DVec2::new(100.0, 0.49), sq, 0), 1.0).unwrap();
        let wall = Wall::segment(DVec2::new(90.0, 0.0), DVec2::new(110.0, 0.0), 0);
        let config =
            Configuration { position: &bodies.position, angle: &bodies.angle, periodic: None, pass_through: None };
        let mut out = Vec::new();
        body_wall(&bodies, &config, 0, 0, &wall, 0.05, &mut out);
        assert_eq!(out.len(), 2, "{out:?}");
        for c in &out {
            assert!((c.normal - DVec2::Y).length() < 1e-5, "{c:?}");
            assert!((c.gap + 0.01).abs() < 1e-5, "{c:?}");
            assert!((c.point.y - 0.0).abs() < 0.01 && (c.point.x - 100.0).abs() > 0.49, "{c:?}");
        }
    }
}
