//! Exact narrow phase. Disk–disk and disk–segment are closed-form in f64 (a clump's disks each
//! as a disk, a contact per pair of disks that touch); disk–polygon goes
//! through parry2d (f32, posed relative to the disk so precision follows grain size, not the
//! distance from the origin); polygon–polygon and polygon–segment by SAT and clipping in f64.

use glam::{DVec2, Vec2};
use parry2d::math::Pose;
use parry2d::query;
use parry2d::shape::{Ball, ConvexPolygon};

use super::polygon_clip::polygon_polygon;
use super::{Antagonist, Configuration, DetectedContact};
use crate::world::{Bodies, BodyShape, Wall, WallShape};

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

/// Contact of a disk (centre `x`, radius `r`) with a convex polygon posed at `xp`, angle `ap`,
/// through parry2d, posed relative to the disk so that precision follows grain size.
/// Returns (point, normal from the polygon to the disk, gap).
fn disk_polygon(
    x: DVec2,
    r: f64,
    polygon: &ConvexPolygon,
    xp: DVec2,
    ap: f64,
    alert: f64,
) -> Option<(DVec2, DVec2, f64)> {
    let pose_disk = Pose::new(Vec2::ZERO, 0.0);
    let pose_poly = Pose::new(v32(xp - x), ap as f32);
    let ball = Ball::new(r as f32);
    match query::contact(&pose_disk, &ball, &pose_poly, polygon, alert as f32) {
        Ok(Some(c)) => Some((x + 0.5 * (v64(c.point1) + v64(c.point2)), -v64(c.normal1), c.dist as f64)),
        _ => None,
    }
}

fn v32(v: DVec2) -> Vec2 {
    Vec2::new(v.x as f32, v.y as f32)
}

fn v64(v: Vec2) -> DVec2 {
    DVec2::new(v.x as f64, v.y as f64)
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
        (BodyShape::Polygon(_), BodyShape::Polygon(_)) => {
            let mut pts = Vec::new();
            let b: Vec<DVec2> = world_vertices(bodies, config, j).into_iter().map(|v| v + image).collect();
            let a = world_vertices(bodies, config, i);
            polygon_polygon(&a, &b, alert, &mut pts);
            for c in pts {
                push(out, c.feature, c.point, c.normal, c.gap);
            }
        }
        (BodyShape::Polygon(p), _) => {
            let polygon = &bodies.polygons[p as usize].parry;
            for (b, (x, radius)) in round_pieces(bodies, config, j, image).into_iter().enumerate() {
                if let Some((point, normal, gap)) = disk_polygon(x, radius, polygon, xi, config.angle_of(i), alert) {
                    push(out, piece_pair(0, b), point, -normal, gap);
                }
            }
        }
        (_, BodyShape::Polygon(p)) => {
            let polygon = &bodies.polygons[p as usize].parry;
            for (a, (x, radius)) in round_pieces(bodies, config, i, DVec2::ZERO).into_iter().enumerate() {
                if let Some((point, normal, gap)) = disk_polygon(x, radius, polygon, xj, config.angle_of(j), alert) {
                    push(out, piece_pair(a, 0), point, normal, gap);
                }
            }
        }
        // Disks and clumps: every disk of one against every disk of the other.
        (_, _) => {
            let theirs = round_pieces(bodies, config, j, image);
            for (a, (xa, ra)) in round_pieces(bodies, config, i, DVec2::ZERO).into_iter().enumerate() {
                for (b, &(xb, rb)) in theirs.iter().enumerate() {
                    let (gap, normal, point) = disk_disk(xa, ra, xb, rb);
                    if gap <= alert {
                        push(out, piece_pair(a, b), point, normal, gap);
                    }
                }
            }
        }
    }
}

/// A disk's or a clump's disks in the world frame, body `k` shifted by `image` (empty for a
/// polygon).
fn round_pieces(bodies: &Bodies, config: &Configuration, k: usize, image: DVec2) -> Vec<(DVec2, f64)> {
    let x = config.position[k] + image;
    match bodies.shape[k] {
        BodyShape::Disk { radius } => vec![(x, radius)],
        BodyShape::Clump(c) => bodies.clump_disks(c, x, config.angle_of(k)).collect(),
        BodyShape::Polygon(_) => Vec::new(),
    }
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
            if let Some((point, normal, gap)) = disk_polygon(x, radius, &poly.parry, wall.center, wall.angle, alert) {
                push(out, a as u64, point, normal, gap);
            }
        }
    };
    match (bodies.shape[k], &wall.shape) {
        (BodyShape::Disk { radius }, _) => round(out, 0, x, radius),
        (BodyShape::Clump(c), _) => {
            for (a, (x, radius)) in bodies.clump_disks(c, x, config.angle_of(k)).enumerate() {
                round(out, a, x, radius);
            }
        }
        (BodyShape::Polygon(_), _) => {
            let mut pts = Vec::new();
            polygon_polygon(&world_vertices(bodies, config, k), &wall.world_points(), alert, &mut pts);
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
    fn a_square_resting_on_a_segment_gets_two_contacts_pointing_up() {
        let mut bodies = Bodies::new(true);
        let sq = vec![DVec2::new(-0.5, -0.5), DVec2::new(0.5, -0.5), DVec2::new(0.5, 0.5), DVec2::new(-0.5, 0.5)];
        bodies.add(&BodySpec::polygon(DVec2::new(100.0, 0.49), sq, 0), 1.0).unwrap();
        let wall = Wall::segment(DVec2::new(90.0, 0.0), DVec2::new(110.0, 0.0), 0);
        let config = Configuration { position: &bodies.position, angle: &bodies.angle, periodic: None };
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
