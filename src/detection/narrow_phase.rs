//! Exact narrow phase. Disk–disk and disk–segment are closed-form in f64; every pair with a
//! polygon goes through parry2d (f32), posed relative to body `i` so that precision depends on
//! the grains' size, not on their distance from the origin.

use glam::{DVec2, Vec2};
use parry2d::math::Pose;
use parry2d::query::{self, details::contact_manifold_pfm_pfm, ContactManifold};
use parry2d::shape::{Ball, ConvexPolygon, Segment, Shape};

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

enum Geometry<'a> {
    Disk(f64),
    Polygon(&'a ConvexPolygon),
    Segment(DVec2, DVec2),
}

fn body_geometry(bodies: &Bodies, k: usize) -> Geometry<'_> {
    match bodies.shape[k] {
        BodyShape::Disk { radius } => Geometry::Disk(radius),
        BodyShape::Polygon(p) => Geometry::Polygon(&bodies.polygons[p as usize].parry),
    }
}

fn v32(v: DVec2) -> Vec2 {
    Vec2::new(v.x as f32, v.y as f32)
}

fn v64(v: Vec2) -> DVec2 {
    DVec2::new(v.x as f64, v.y as f64)
}

/// Contacts between shape 1 (body `i`, at `x1` with angle `a1`) and shape 2 (at `x2`, angle `a2`)
/// through parry2d. Every parry query is posed relative to `x1`.
#[allow(clippy::too_many_arguments)]
fn parry_contacts(
    g1: &Geometry,
    x1: DVec2,
    a1: f64,
    g2: &Geometry,
    x2: DVec2,
    a2: f64,
    alert: f64,
    mut emit: impl FnMut(u64, DVec2, DVec2, f64),
) {
    let pose1 = Pose::new(Vec2::ZERO, a1 as f32);
    let pose2 = Pose::new(v32(x2 - x1), a2 as f32);
    let segment;
    let ball1;
    let ball2;
    let s1: &dyn Shape = match g1 {
        Geometry::Disk(r) => {
            ball1 = Ball::new(*r as f32);
            &ball1
        }
        Geometry::Polygon(p) => *p,
        Geometry::Segment(..) => unreachable!("shape 1 is always a body"),
    };
    let s2: &dyn Shape = match g2 {
        Geometry::Disk(r) => {
            ball2 = Ball::new(*r as f32);
            &ball2
        }
        Geometry::Polygon(p) => *p,
        Geometry::Segment(a, b) => {
            segment = Segment::new(v32(*a), v32(*b));
            &segment
        }
    };
    let both_polygonal = !matches!(g1, Geometry::Disk(_)) && !matches!(g2, Geometry::Disk(_));
    if both_polygonal {
        let pos12 = pose1.inv_mul(&pose2);
        let mut manifold: ContactManifold<(), ()> = ContactManifold::new();
        match (g1, g2) {
            (Geometry::Polygon(p1), Geometry::Polygon(p2)) => {
                contact_manifold_pfm_pfm(&pos12, *p1, 0.0, None, *p2, 0.0, None, alert as f32, &mut manifold)
            }
            (Geometry::Polygon(p1), Geometry::Segment(a, b)) => {
                let seg = Segment::new(v32(*a), v32(*b));
                contact_manifold_pfm_pfm(&pos12, *p1, 0.0, None, &seg, 0.0, None, alert as f32, &mut manifold)
            }
            _ => return,
        }
        let n_world = -v64(pose1.rotation * manifold.local_n1);
        for c in &manifold.points {
            let p1 = x1 + v64(pose1 * c.local_p1);
            let p2 = x1 + v64(pose2 * c.local_p2);
            let feature = ((c.fid1.0 as u64) << 32) | c.fid2.0 as u64;
            emit(feature, 0.5 * (p1 + p2), n_world, c.dist as f64);
        }
    } else if let Ok(Some(c)) = query::contact(&pose1, s1, &pose2, s2, alert as f32) {
        let p = x1 + 0.5 * (v64(c.point1) + v64(c.point2));
        emit(0, p, -v64(c.normal1), c.dist as f64);
    }
}

/// Contacts between bodies `i < j`.
pub fn body_body(bodies: &Bodies, config: &Configuration, i: usize, j: usize, alert: f64, out: &mut Vec<DetectedContact>) {
    let (xi, xj) = (config.position[i], config.position[j]);
    if let (BodyShape::Disk { radius: ri }, BodyShape::Disk { radius: rj }) = (bodies.shape[i], bodies.shape[j]) {
        let (gap, normal, point) = disk_disk(xi, ri, xj, rj);
        if gap <= alert {
            out.push(DetectedContact { i, other: Antagonist::Body(j), feature: 0, point, normal, gap });
        }
        return;
    }
    if bodies.inv_mass[i] == 0.0 && bodies.inv_mass[j] == 0.0 {
        return;
    }
    let (gi, gj) = (body_geometry(bodies, i), body_geometry(bodies, j));
    // parry's shape 1 must be a body; a disk–polygon pair is posed with the polygon first when needed.
    parry_contacts(&gi, xi, config.angle_of(i), &gj, xj, config.angle_of(j), alert, |feature, point, normal, gap| {
        out.push(DetectedContact { i, other: Antagonist::Body(j), feature, point, normal, gap })
    });
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
    let rot = DVec2::from_angle(wall.angle);
    if let (BodyShape::Disk { radius }, WallShape::Segment { a, b }) = (bodies.shape[k], &wall.shape) {
        let (gap, normal, point) = disk_segment(x, radius, wall.center + rot.rotate(*a), wall.center + rot.rotate(*b));
        if gap <= alert {
            out.push(DetectedContact { i: k, other: Antagonist::Wall(w), feature: 0, point, normal, gap });
        }
        return;
    }
    let gw = match &wall.shape {
        WallShape::Segment { a, b } => Geometry::Segment(*a, *b),
        WallShape::Polygon(p) => Geometry::Polygon(&p.parry),
    };
    parry_contacts(&body_geometry(bodies, k), x, config.angle_of(k), &gw, wall.center, wall.angle, alert, |feature, point, normal, gap| {
        out.push(DetectedContact { i: k, other: Antagonist::Wall(w), feature, point, normal, gap })
    });
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
        let config = Configuration { position: &bodies.position, angle: &bodies.angle };
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
