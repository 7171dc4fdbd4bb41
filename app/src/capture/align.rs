//! Alignment from the images: the sensors give each shot's starting pose; the overlaps between
//! shots then correct them, so seams disappear even when the pose estimate was a few degrees
//! off.
//!
//! First, gravity is kept: the accelerometer's tilt is good to about half a degree, while the
//! heading (magnetometer and gyroscope) carries errors of several degrees that change between
//! shots. So each shot gets one unknown, a turn `h_i` about the world vertical (corrected pose
//! `Rz(h_i)·R_i`). For two shots turned about the same axis the photometric mismatch of their
//! overlap depends only on `h_j − h_i`, so:
//!
//! 1. per overlapping pair, `δ_ij` = the relative turn that best matches the overlap (sum of
//!    squared differences in linear light over a grid of the overlap's directions: a coarse
//!    search on a blurred, half-resolution level of the image pyramid, then a fine search and a
//!    parabola through the three best costs at full resolution);
//! 2. jointly over all shots, the turns minimising `Σ w_ij (h_j − h_i − δ_ij)²` with the front
//!    shot's turn fixed at 0 (it defines the reference heading) and a weak pull of every turn
//!    towards 0 (the sensor pose), a small linear least-squares problem; pairs whose match
//!    disagrees with the joint solution by more than [`OUTLIER_DEG`] are dropped and the system
//!    solved again;
//! 3. then every shot's whole orientation (tilt too: the accelerometer's per-shot tilt error of
//!    a few tenths of a degree cost the faces more than the yaw left after step 2), refined
//!    jointly to a fraction of a pixel by direct photometric alignment of all overlaps
//!    ([`refine_shots`]); the capture's vertical is the mean of the sensor tilts;
//! 4. then the whole capture is levelled by the accelerometer held before each shot
//!    ([`super::gravity::level`]: the images cannot see a tilt common to all shots, and the mean
//!    of the fusion filter's tilts errs by 0.1–0.45°), where at least three shots held it.

use super::dense_solve::solve_dense;
use super::gravity::{Leveling, level};
use super::projection::Pinhole;
use super::reproject::{Shot, sample_linear};
use glam::{Quat, Vec2, Vec3};

/// Largest correction searched per pair (degrees).
pub const SEARCH_DEG: f32 = 6.0;
/// Coarse search step (degrees) on the half-resolution level.
const COARSE_STEP_DEG: f32 = 0.5;
/// Fine search step (degrees) at full resolution.
const FINE_STEP_DEG: f32 = 0.1;
/// Grid of directions laid over each shot's frame to find the overlap.
const GRID: (u32, u32) = (48, 36);
/// Fewest overlap directions a pair needs to be matched.
const MIN_OVERLAP: usize = 60;
/// Weight of the pull of each turn towards the sensor pose, relative to one overlap sample.
const PRIOR_WEIGHT: f64 = 2.0;
/// Pairs disagreeing with the joint solution by more than this (degrees) are dropped.
pub const OUTLIER_DEG: f64 = 1.0;

/// The measured relative turn of one pair of shots.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairMatch {
    pub i: usize,
    pub j: usize,
    /// Turn of shot j relative to shot i about the world vertical (degrees).
    pub delta_deg: f64,
    /// Overlap directions used.
    pub samples: usize,
}

fn turn(deg: f32) -> Quat {
    Quat::from_rotation_z(deg.to_radians())
}

/// A 2×2 box-filtered half-resolution copy (the pyramid's next level) in linear light, sampled
/// back through [`sample_linear`]'s interface by scaling positions by one half.
struct Level {
    width: u32,
    height: u32,
    rgb: Vec<[f32; 3]>,
}

impl Level {
    fn half(shot: &Shot) -> Level {
        let img = &shot.image;
        let (w, h) = (img.width / 2, img.height / 2);
        let mut rgb = Vec::with_capacity((w * h) as usize);
        for y in 0..h {
            for x in 0..w {
                let c = sample_linear(img, Vec2::new(2.0 * x as f32 + 1.0, 2.0 * y as f32 + 1.0));
                rgb.push(c);
            }
        }
        Level { width: w.max(1), height: h.max(1), rgb }
    }

    fn sample(&self, p: Vec2) -> [f32; 3] {
        let x = (p.x - 0.5).clamp(0.0, (self.width - 1) as f32);
        let y = (p.y - 0.5).clamp(0.0, (self.height - 1) as f32);
        let (x0, y0) = (x as usize, y as usize);
        let (x1, y1) = ((x0 + 1).min(self.width as usize - 1), (y0 + 1).min(self.height as usize - 1));
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        let w = self.width as usize;
        let px = |xx: usize, yy: usize| self.rgb[yy * w + xx];
        std::array::from_fn(|c| {
            let top = px(x0, y0)[c] + (px(x1, y0)[c] - px(x0, y0)[c]) * fx;
            let bottom = px(x0, y1)[c] + (px(x1, y1)[c] - px(x0, y1)[c]) * fx;
            top + (bottom - top) * fy
        })
    }
}

/// Directions (world) on a grid over shot `a`'s frame that shot `b` also sees, with a margin
/// of the search range so every trial turn keeps them inside b's frame.
fn overlap(camera: &Pinhole, a: &Shot, b: &Shot) -> Vec<Vec3> {
    let inset = (SEARCH_DEG.to_radians() / camera.tan_half_h.atan()).min(0.5);
    let inv_b = b.pose.inverse();
    let mut dirs = Vec::new();
    for gy in 0..GRID.1 {
        for gx in 0..GRID.0 {
            let px = (gx as f32 + 0.5) / GRID.0 as f32 * camera.width as f32;
            let py = (gy as f32 + 0.5) / GRID.1 as f32 * camera.height as f32;
            let d = (a.pose * camera.pixel_to_dir(px, py)).normalize();
            if camera.to_ndc(inv_b * d).is_some_and(|n| n.x.abs() <= 1.0 - inset && n.y.abs() <= 1.0 - inset) {
                dirs.push(d);
            }
        }
    }
    dirs
}

/// Mean squared difference (linear light) between shot a's colours `ca` at `dirs` and shot b
/// turned by `deg`, sampled by `sample_b` at pixel positions.
fn cost(camera: &Pinhole, dirs: &[Vec3], ca: &[[f32; 3]], b: &Shot, deg: f32, sample_b: &impl Fn(Vec2) -> [f32; 3]) -> f64 {
    cost_rotated(camera, dirs, ca, b, turn(deg), sample_b)
}

/// [`cost`] with shot b rotated by any world-frame rotation `rot`.
fn cost_rotated(camera: &Pinhole, dirs: &[Vec3], ca: &[[f32; 3]], b: &Shot, rot: Quat, sample_b: &impl Fn(Vec2) -> [f32; 3]) -> f64 {
    // Shot b rotated: its pose is rot·R_b, so a world direction d lands where R_b⁻¹·rot⁻¹·d
    // does.
    let inv = b.pose.inverse() * rot.inverse();
    let mut sum = 0.0f64;
    let mut n = 0usize;
    for (d, c) in dirs.iter().zip(ca) {
        let Some(ndc) = camera.to_ndc(inv * *d) else { continue };
        let s = sample_b(camera.ndc_to_pixel(ndc));
        sum += (0..3).map(|k| f64::from(s[k] - c[k]).powi(2)).sum::<f64>();
        n += 1;
    }
    if n == 0 { f64::INFINITY } else { sum / n as f64 }
}

/// Shot a's colours along the overlap's directions, or `None` when the overlap is featureless
/// (flat sky: no variance in green), which cannot be matched.
fn overlap_colours(camera: &Pinhole, a: &Shot, dirs: &[Vec3]) -> Option<Vec<[f32; 3]>> {
    let inv_a = a.pose.inverse();
    let ca: Vec<[f32; 3]> =
        dirs.iter().map(|d| camera.to_ndc(inv_a * *d).map_or([0.0; 3], |n| sample_linear(&a.image, camera.ndc_to_pixel(n)))).collect();
    let mean: f32 = ca.iter().map(|c| c[1]).sum::<f32>() / ca.len() as f32;
    let var: f32 = ca.iter().map(|c| (c[1] - mean).powi(2)).sum::<f32>() / ca.len() as f32;
    (var >= 1e-6).then_some(ca)
}

/// The relative turn of shot b against shot a that best matches their overlap, or `None` when
/// they overlap too little or the overlap is featureless.
pub fn match_pair(camera: &Pinhole, a: &Shot, b: &Shot) -> Option<(f64, usize)> {
    let dirs = overlap(camera, a, b);
    if dirs.len() < MIN_OVERLAP {
        return None;
    }
    let ca = overlap_colours(camera, a, &dirs)?;
    let half = Level::half(b);
    let coarse = |p: Vec2| half.sample(p * 0.5);
    let steps = (SEARCH_DEG / COARSE_STEP_DEG) as i32;
    let (best, _) = (-steps..=steps)
        .map(|k| k as f32 * COARSE_STEP_DEG)
        .map(|deg| (deg, cost(camera, &dirs, &ca, b, deg, &coarse)))
        .min_by(|x, y| x.1.total_cmp(&y.1))?;
    let full = |p: Vec2| sample_linear(&b.image, p);
    fine_turn(best, |deg| cost(camera, &dirs, &ca, b, deg, &full)).map(|delta| (delta, dirs.len()))
}

/// The turn (degrees) at full resolution around a coarse `best`: `cost` at every
/// [`FINE_STEP_DEG`] within a coarse step, a parabola through the three costs around the
/// minimum; `None` when it lands outside the search range.
fn fine_turn(best: f32, cost: impl Fn(f32) -> f64) -> Option<f64> {
    let k = (COARSE_STEP_DEG / FINE_STEP_DEG) as i32;
    let fine: Vec<(f32, f64)> = (-k..=k).map(|i| best + i as f32 * FINE_STEP_DEG).map(|deg| (deg, cost(deg))).collect();
    let (i, _) = fine.iter().enumerate().min_by(|x, y| x.1.1.total_cmp(&y.1.1))?;
    let delta = if i == 0 || i + 1 == fine.len() {
        f64::from(fine[i].0)
    } else {
        // Parabola through the three costs around the minimum.
        let (c0, c1, c2) = (fine[i - 1].1, fine[i].1, fine[i + 1].1);
        let denom = c0 - 2.0 * c1 + c2;
        let off = if denom > 0.0 { 0.5 * (c0 - c2) / denom } else { 0.0 };
        f64::from(fine[i].0) + off.clamp(-0.5, 0.5) * f64::from(FINE_STEP_DEG)
    };
    (delta.abs() < f64::from(SEARCH_DEG)).then_some(delta)
}

/// Relative tilt searched (degrees, about each world-horizontal axis) when a new shot is
/// matched while capturing ([`turn_against`]): the guidance's held pose is tilted by up to
/// ~4° at `bad` noise (the gyroscope bias's lag in the fusion filter, the accelerometer's
/// bias), and a turn searched alone over a tilted overlap finds a wrong minimum.
const TILT_SEARCH_DEG: f32 = 4.5;
/// Coarse tilt step (degrees) on the half-resolution level.
const TILT_COARSE_STEP_DEG: f32 = 1.5;

/// [`match_pair`] with the relative tilt of the two shots searched too (a coarse search over
/// turn × tilt on the half-resolution level, a finer one around its best, then the turn at full
/// resolution with a parabola): the turn about the vertical (degrees) that best matches b to a.
fn match_pair_tilted(camera: &Pinhole, a: &Shot, b: &Shot, dirs: &[Vec3]) -> Option<f64> {
    if dirs.len() < MIN_OVERLAP {
        return None;
    }
    let ca = overlap_colours(camera, a, dirs)?;
    let rot = |yaw: f32, tx: f32, ty: f32| turn(yaw) * Quat::from_scaled_axis(Vec3::new(tx.to_radians(), ty.to_radians(), 0.0));
    let half = Level::half(b);
    let coarse = |p: Vec2| half.sample(p * 0.5);
    // Every other direction for the coarse search (it only has to land near the minimum).
    let (sub_dirs, sub_ca): (Vec<Vec3>, Vec<[f32; 3]>) = dirs.iter().zip(&ca).step_by(2).map(|(d, c)| (*d, *c)).unzip();
    let search = |yaws: &[f32], tilts: &[f32], centre: (f32, f32, f32), dirs: &[Vec3], ca: &[[f32; 3]]| {
        let mut best = (centre, f64::INFINITY);
        for &y in yaws {
            for &tx in tilts {
                for &ty in tilts {
                    let at = (centre.0 + y, centre.1 + tx, centre.2 + ty);
                    let c = cost_rotated(camera, dirs, ca, b, rot(at.0, at.1, at.2), &coarse);
                    if c < best.1 {
                        best = (at, c);
                    }
                }
            }
        }
        best.0
    };
    let steps = |range: f32, step: f32| {
        let k = (range / step).round() as i32;
        (-k..=k).map(|i| i as f32 * step).collect::<Vec<_>>()
    };
    let best =
        search(&steps(SEARCH_DEG, COARSE_STEP_DEG), &steps(TILT_SEARCH_DEG, TILT_COARSE_STEP_DEG), (0.0, 0.0, 0.0), &sub_dirs, &sub_ca);
    let best = search(&steps(COARSE_STEP_DEG, 0.25), &steps(TILT_COARSE_STEP_DEG, 0.5), best, dirs, &ca);
    let full = |p: Vec2| sample_linear(&b.image, p);
    fine_turn(best.0, |deg| cost_rotated(camera, dirs, &ca, b, rot(deg, best.1, best.2), &full))
}

/// The turn about the world vertical (degrees) that best aligns a new shot with the earlier
/// shots, and the index in `earlier` of the shot it was matched against: of the earlier shots
/// whose view overlaps it, the one with the largest overlap that can be matched, the relative
/// tilt searched too ([`match_pair_tilted`]). `None` when no earlier shot overlaps it enough or
/// every overlap is featureless. While capturing, this measures the drift of the heading the
/// guidance uses (the gyroscope's, whose bias about the vertical is not observable by the
/// accelerometer) since that earlier shot.
pub fn turn_against(camera: &Pinhole, earlier: &[Shot], new: &Shot) -> Option<(usize, f64)> {
    let diag = (camera.tan_half_h.hypot(camera.tan_half_v)).atan() * 2.0;
    let axis = new.pose * Vec3::NEG_Z;
    let mut candidates: Vec<(usize, Vec<Vec3>)> = earlier
        .iter()
        .enumerate()
        .filter(|(_, s)| (s.pose * Vec3::NEG_Z).angle_between(axis) < diag)
        .map(|(i, s)| (i, overlap(camera, s, new)))
        .filter(|(_, dirs)| dirs.len() >= MIN_OVERLAP)
        .collect();
    candidates.sort_by_key(|(_, dirs)| std::cmp::Reverse(dirs.len()));
    candidates.iter().find_map(|(i, dirs)| match_pair_tilted(camera, &earlier[*i], new, dirs).map(|delta| (*i, delta)))
}

/// Solve `min Σ w (h_j − h_i − δ)² + PRIOR_WEIGHT Σ h²` with `h[fixed] = 0` (dense normal
/// equations; n is a few dozen at most).
fn solve(n: usize, fixed: usize, pairs: &[PairMatch]) -> Vec<f64> {
    let mut a = vec![vec![0.0f64; n]; n];
    let mut b = vec![0.0f64; n];
    for (i, row) in a.iter_mut().enumerate() {
        row[i] += PRIOR_WEIGHT;
    }
    for p in pairs {
        let w = p.samples as f64;
        a[p.i][p.i] += w;
        a[p.j][p.j] += w;
        a[p.i][p.j] -= w;
        a[p.j][p.i] -= w;
        b[p.j] += w * p.delta_deg;
        b[p.i] -= w * p.delta_deg;
    }
    // h[fixed] = 0.
    a[fixed].iter_mut().for_each(|v| *v = 0.0);
    a.iter_mut().for_each(|row| row[fixed] = 0.0);
    a[fixed][fixed] = 1.0;
    b[fixed] = 0.0;
    solve_dense(a, b).0
}

/// What the alignment did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Alignment {
    /// Turn about the world vertical applied to each shot (degrees), in `shots` order.
    pub turns_deg: Vec<f64>,
    /// Pairs matched and kept.
    pub pairs: Vec<PairMatch>,
    /// Pairs dropped as outliers.
    pub dropped: usize,
    /// The joint refinement of every shot's whole orientation after the turns ([`refine_shots`]).
    pub refinement: Refinement,
    /// The capture's vertical from the accelerometer held at the shots ([`level`]); `None`
    /// where too few shots held it: the vertical is then the mean of the sensor tilts.
    pub leveling: Option<Leveling>,
}

/// Align `shots` from their overlaps (see the module documentation): each shot's turn about the
/// vertical ([`align_turns`]), then every shot's whole orientation refined jointly
/// ([`refine_shots`]), then the capture levelled by the shots' held gravity
/// ([`super::gravity::level`]); shot `fixed` (the front) keeps its heading. Returns the
/// corrected shots and what was done (`turns_deg`: the whole turn about the vertical, all steps').
pub fn align_shots(camera: &Pinhole, shots: &[Shot], fixed: usize) -> (Vec<Shot>, Alignment) {
    let (turned, alignment) = align_turns(camera, shots, fixed);
    let (mut aligned, refinement) = refine_shots(camera, &turned, fixed);
    // The capture's vertical from the accelerometer held at the shots, where they have it.
    let leveling = level(&aligned.iter().map(|s| s.pose).collect::<Vec<_>>(), &aligned.iter().map(|s| s.gravity).collect::<Vec<_>>());
    if let Some(l) = leveling {
        for s in &mut aligned {
            s.pose = (l.correction * s.pose).normalize();
        }
    }
    let turns_deg = shots.iter().zip(&aligned).map(|(s, a)| yaw_deg(a.pose * s.pose.inverse())).collect();
    (aligned, Alignment { turns_deg, refinement, leveling, ..alignment })
}

/// The first step of [`align_shots`]: each shot's turn about the vertical from the pairs'
/// matches, jointly (steps 1 and 2 of the module documentation); shot `fixed` keeps its pose.
pub fn align_turns(camera: &Pinhole, shots: &[Shot], fixed: usize) -> (Vec<Shot>, Alignment) {
    let n = shots.len();
    if n < 2 || fixed >= n {
        return (shots.to_vec(), Alignment { turns_deg: vec![0.0; n], ..Alignment::default() });
    }
    // Pairs whose view axes are closer than the frame's diagonal field of view can overlap.
    let diag = (camera.tan_half_h.hypot(camera.tan_half_v)).atan() * 2.0;
    let candidates: Vec<(usize, usize)> = (0..n)
        .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
        .filter(|&(i, j)| (shots[i].pose * Vec3::NEG_Z).angle_between(shots[j].pose * Vec3::NEG_Z) < diag)
        .collect();
    let matches: Vec<PairMatch> = std::thread::scope(|s| {
        let workers = std::thread::available_parallelism().map_or(1, |k| k.get()).min(candidates.len().max(1));
        let chunks: Vec<Vec<(usize, usize)>> =
            (0..workers).map(|w| candidates.iter().copied().skip(w).step_by(workers).collect()).collect();
        let handles: Vec<_> = chunks
            .into_iter()
            .map(|chunk| {
                s.spawn(move || {
                    chunk
                        .into_iter()
                        .filter_map(|(i, j)| {
                            match_pair(camera, &shots[i], &shots[j]).map(|(delta_deg, samples)| PairMatch { i, j, delta_deg, samples })
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles.into_iter().flat_map(|h| h.join().unwrap_or_default()).collect()
    });
    let mut pairs = matches;
    let mut h = solve(n, fixed, &pairs);
    let before = pairs.len();
    pairs.retain(|p| (h[p.j] - h[p.i] - p.delta_deg).abs() <= OUTLIER_DEG);
    let dropped = before - pairs.len();
    if dropped > 0 {
        h = solve(n, fixed, &pairs);
    }
    let aligned = shots.iter().zip(&h).map(|(s, d)| Shot { pose: (turn(*d as f32) * s.pose).normalize(), ..s.clone() }).collect();
    (aligned, Alignment { turns_deg: h, pairs, dropped, ..Alignment::default() })
}

/// The angle (degrees) of a world-frame rotation's twist about the world vertical.
fn yaw_deg(q: Quat) -> f64 {
    let q = q.as_dquat().normalize();
    let q = if q.w < 0.0 { -q } else { q };
    (2.0 * q.z.atan2(q.w)).to_degrees()
}

/// 1σ of the accelerometer's tilt per shot (degrees): the pull of each shot's tilt towards its
/// sensor pose in the refinement (the overlaps fix the relative tilts far more tightly). During
/// the refinement the capture's vertical is the mean of the sensor tilts; [`align_shots`] then
/// levels it by the accelerometer held at the shots ([`super::gravity`]), where they hold it.
const TILT_SIGMA_DEG: f64 = 0.5;
/// 1σ of each shot's heading after the pair search (degrees): a weak pull that keeps a shot
/// without usable overlaps where it is (3° and 30° measured the same).
const YAW_SIGMA_DEG: f64 = 30.0;
/// 1σ of a photometric residual (linear light, per channel) after alignment: resampling and
/// 8-bit quantisation. It weighs the overlaps against the pulls above.
const PHOTO_SIGMA: f64 = 0.01;
/// Residuals beyond this many σ weigh less (Huber): moving things, a reflection.
const HUBER_K: f64 = 3.0;
/// Gauss–Newton iterations on the half-resolution level, then at full resolution.
const REFINE_ITERATIONS: [usize; 2] = [8, 4];
/// Directions laid over each shot's frame for the refinement's overlaps.
const REFINE_GRID: (u32, u32) = (64, 48);
/// Overlap directions keep this far inside both frames (normalised units).
const REFINE_INSET: f32 = 0.02;
/// Largest change (degrees) one refinement step may make to a shot; a larger step is halved.
const REFINE_MAX_STEP_DEG: f64 = 1.0;

/// What the refinement did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Refinement {
    /// Angle (degrees) each shot's orientation was changed by, in `shots` order.
    pub rotations_deg: Vec<f64>,
    /// Pairs whose overlaps took part, and their directions.
    pub pairs: usize,
    pub samples: usize,
    /// RMS photometric residual (linear light) over the overlaps at full resolution, before and
    /// after.
    pub rms_before: f64,
    pub rms_after: f64,
}

/// Sub-pixel joint refinement of every shot's whole orientation (three angles, not only the
/// turn about the vertical): direct photometric alignment of all overlaps at once, after
/// Szeliski 2006 ("Image Alignment and Stitching: A Tutorial", Found. Trends Comput. Graph.
/// Vis. 2(1), §3.2 "Incremental refinement" and §5.1 "Bundle adjustment", with rotations as the
/// motion model, §2.1.5). Unknowns: a small world-frame rotation ω_k per shot, pose
/// `exp(ω_k)·R_k`. Per overlap direction d of a pair (a, b), the residual is
/// `I_a(π(R_a⁻¹ exp(−ω_a) d)) − I_b(π(R_b⁻¹ exp(−ω_b) d))` per channel in linear light; its
/// derivatives by central differences half a pixel wide. Gauss–Newton on the normal equations
/// of all shots together, with each shot's tilt (ω_x, ω_y) pulled towards its sensor pose
/// ([`TILT_SIGMA_DEG`]: gravity is kept) and its heading weakly ([`YAW_SIGMA_DEG`]), the
/// shot `fixed`'s heading held (it defines the reference heading); a few iterations on the
/// half-resolution level, then at full resolution. Kept only when it lowers the residual.
pub fn refine_shots(camera: &Pinhole, shots: &[Shot], fixed: usize) -> (Vec<Shot>, Refinement) {
    let n = shots.len();
    let unchanged = || (shots.to_vec(), Refinement { rotations_deg: vec![0.0; n], ..Refinement::default() });
    if n < 2 || fixed >= n {
        return unchanged();
    }
    let diag = (camera.tan_half_h.hypot(camera.tan_half_v)).atan() * 2.0;
    let pairs: Vec<(usize, usize, Vec<Vec3>)> = (0..n)
        .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
        .filter(|&(i, j)| (shots[i].pose * Vec3::NEG_Z).angle_between(shots[j].pose * Vec3::NEG_Z) < diag)
        .map(|(i, j)| (i, j, refine_overlap(camera, &shots[i], &shots[j])))
        .filter(|(_, _, d)| d.len() >= MIN_OVERLAP)
        .collect();
    if pairs.is_empty() {
        return unchanged();
    }
    let halves: Vec<Level> = shots.iter().map(Level::half).collect();
    let mut poses: Vec<Quat> = shots.iter().map(|s| s.pose).collect();
    let mut acc = vec![glam::DVec3::ZERO; n];
    let rms_before = normal_equations(camera, shots, &halves, &poses, &pairs, 1, false).rms;
    let prior = |k: usize| {
        let yaw = if k == fixed { 1e-4 } else { YAW_SIGMA_DEG };
        let t = (PHOTO_SIGMA / TILT_SIGMA_DEG.to_radians()).powi(2);
        glam::DVec3::new(t, t, (PHOTO_SIGMA / yaw.to_radians()).powi(2))
    };
    for (level, &iterations) in REFINE_ITERATIONS.iter().enumerate() {
        for _ in 0..iterations {
            let mut eq = normal_equations(camera, shots, &halves, &poses, &pairs, level, true);
            for (k, a) in acc.iter().enumerate() {
                let p = prior(k);
                for m in 0..3 {
                    eq.h[3 * k + m][3 * k + m] += p[m];
                    eq.g[3 * k + m] += p[m] * a[m];
                }
            }
            let step = solve_dense(eq.h, eq.g.iter().map(|v| -v).collect()).0;
            let largest = step.iter().fold(0.0f64, |m, v| m.max(v.abs())).to_degrees();
            let scale = if largest > REFINE_MAX_STEP_DEG { REFINE_MAX_STEP_DEG / largest } else { 1.0 };
            for k in 0..n {
                let w = glam::DVec3::new(step[3 * k], step[3 * k + 1], step[3 * k + 2]) * scale;
                acc[k] += w;
                poses[k] = (glam::DQuat::from_scaled_axis(w).as_quat() * poses[k]).normalize();
            }
            // The gauge. The overlaps fix the shots' orientations relative to each other only;
            // the capture's vertical is the mean of the sensor tilts and its heading the front's.
            // The pulls above make the system solvable but are far too weak against the
            // overlaps to hold the whole capture (their numerical leakage turned it by tenths of
            // a degree, measured), so the common turn is taken off explicitly.
            let tilt = acc.iter().fold(glam::DVec3::ZERO, |s, a| s + glam::DVec3::new(a.x, a.y, 0.0)) / n as f64;
            let common = glam::DVec3::new(tilt.x, tilt.y, acc[fixed].z);
            let undo = glam::DQuat::from_scaled_axis(-common).as_quat();
            for (a, p) in acc.iter_mut().zip(&mut poses) {
                *a -= common;
                *p = (undo * *p).normalize();
            }
        }
    }
    let rms_after = normal_equations(camera, shots, &halves, &poses, &pairs, 1, false).rms;
    if !(rms_after.is_finite() && rms_after <= rms_before) {
        return unchanged();
    }
    let refined: Vec<Shot> = shots.iter().zip(&poses).map(|(s, p)| Shot { pose: *p, ..s.clone() }).collect();
    let rotations_deg = shots.iter().zip(&poses).map(|(s, p)| f64::from(s.pose.angle_between(*p).to_degrees())).collect();
    let samples = pairs.iter().map(|p| p.2.len()).sum();
    (refined, Refinement { rotations_deg, pairs: pairs.len(), samples, rms_before, rms_after })
}

/// World directions on a grid over shot a's frame that both frames see, [`REFINE_INSET`] inside.
fn refine_overlap(camera: &Pinhole, a: &Shot, b: &Shot) -> Vec<Vec3> {
    let inv_b = b.pose.inverse();
    let inside = |n: Vec2| n.x.abs() <= 1.0 - REFINE_INSET && n.y.abs() <= 1.0 - REFINE_INSET;
    let mut dirs = Vec::new();
    for gy in 0..REFINE_GRID.1 {
        for gx in 0..REFINE_GRID.0 {
            let px = (gx as f32 + 0.5) / REFINE_GRID.0 as f32 * camera.width as f32;
            let py = (gy as f32 + 0.5) / REFINE_GRID.1 as f32 * camera.height as f32;
            let c = camera.pixel_to_dir(px, py);
            let Some(na) = camera.to_ndc(c) else { continue };
            let d = (a.pose * c).normalize();
            if inside(na) && camera.to_ndc(inv_b * d).is_some_and(inside) {
                dirs.push(d);
            }
        }
    }
    dirs
}

/// The Gauss–Newton normal equations of the photometric residuals (scaled by 1/[`PHOTO_SIGMA`]):
/// `h` = JᵀWJ, `g` = JᵀWr over all pairs, and the RMS residual.
struct Normal {
    h: Vec<Vec<f64>>,
    g: Vec<f64>,
    rms: f64,
}

fn normal_equations(
    camera: &Pinhole,
    shots: &[Shot],
    halves: &[Level],
    poses: &[Quat],
    pairs: &[(usize, usize, Vec<Vec3>)],
    level: usize,
    jacobian: bool,
) -> Normal {
    let n = shots.len();
    // Half a pixel of the level, as an angle at the frame's centre.
    let eps = 0.5 * (2.0 * camera.tan_half_v / camera.height as f32) * if level == 0 { 2.0 } else { 1.0 };
    let sample = |k: usize, c: Vec3| -> Option<[f32; 3]> {
        let p = camera.ndc_to_pixel(camera.to_ndc(c)?);
        Some(if level == 0 { halves[k].sample(p * 0.5) } else { sample_linear(&shots[k].image, p) })
    };
    let inverse: Vec<Quat> = poses.iter().map(|q| q.inverse()).collect();
    // Value and 3×3 derivative (channel × world axis) of shot k's colour along direction d.
    let look = |k: usize, d: Vec3| -> Option<([f32; 3], [[f64; 3]; 3])> {
        let v = sample(k, inverse[k] * d)?;
        let mut jac = [[0.0f64; 3]; 3];
        if jacobian {
            for (m, axis) in [Vec3::X, Vec3::Y, Vec3::Z].into_iter().enumerate() {
                let t = axis.cross(d) * eps;
                let (lo, hi) = (sample(k, inverse[k] * (d - t))?, sample(k, inverse[k] * (d + t))?);
                for c in 0..3 {
                    jac[c][m] = f64::from(lo[c] - hi[c]) / (2.0 * f64::from(eps));
                }
            }
        }
        Some((v, jac))
    };
    let per_pair = |(a, b, dirs): &(usize, usize, Vec<Vec3>)| {
        let mut blocks = [[[0.0f64; 3]; 3]; 3];
        let (mut ga, mut gb) = ([0.0f64; 3], [0.0f64; 3]);
        let (mut sq, mut count) = (0.0f64, 0usize);
        for d in dirs {
            let (Some((va, ja)), Some((vb, jb))) = (look(*a, *d), look(*b, *d)) else { continue };
            for c in 0..3 {
                let r = f64::from(va[c] - vb[c]) / PHOTO_SIGMA;
                sq += r * r;
                count += 1;
                if !jacobian {
                    continue;
                }
                let w = if r.abs() <= HUBER_K { 1.0 } else { HUBER_K / r.abs() };
                let (ja, jb) = (ja[c].map(|v| v / PHOTO_SIGMA), jb[c].map(|v| -v / PHOTO_SIGMA));
                for p in 0..3 {
                    ga[p] += w * ja[p] * r;
                    gb[p] += w * jb[p] * r;
                    for q in 0..3 {
                        blocks[0][p][q] += w * ja[p] * ja[q];
                        blocks[1][p][q] += w * ja[p] * jb[q];
                        blocks[2][p][q] += w * jb[p] * jb[q];
                    }
                }
            }
        }
        (blocks, ga, gb, sq, count)
    };
    let results: Vec<(usize, _)> = std::thread::scope(|s| {
        let workers = std::thread::available_parallelism().map_or(1, |k| k.get()).min(pairs.len()).max(1);
        let handles: Vec<_> = (0..workers)
            .map(|w| {
                let per_pair = &per_pair;
                s.spawn(move || pairs.iter().enumerate().skip(w).step_by(workers).map(|(i, p)| (i, per_pair(p))).collect::<Vec<_>>())
            })
            .collect();
        handles.into_iter().flat_map(|h| h.join().unwrap_or_default()).collect()
    });
    let mut h = vec![vec![0.0f64; 3 * n]; 3 * n];
    let mut g = vec![0.0f64; 3 * n];
    let (mut sq, mut count) = (0.0, 0usize);
    for (i, (blocks, ga, gb, s, c)) in results {
        let (a, b) = (pairs[i].0, pairs[i].1);
        sq += s;
        count += c;
        for p in 0..3 {
            g[3 * a + p] += ga[p];
            g[3 * b + p] += gb[p];
            for q in 0..3 {
                h[3 * a + p][3 * a + q] += blocks[0][p][q];
                h[3 * a + p][3 * b + q] += blocks[1][p][q];
                h[3 * b + q][3 * a + p] += blocks[1][p][q];
                h[3 * b + p][3 * b + q] += blocks[2][p][q];
            }
        }
    }
    Normal { h, g, rms: if count > 0 { PHOTO_SIGMA * (sq / count as f64).sqrt() } else { 0.0 } }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::frames::from_heading_pitch_roll;
    use crate::scene::Rgba8Image;
    use std::sync::Arc;

    /// A textured world: colour varies smoothly but quickly with direction (no flat regions).
    fn world(d: Vec3) -> [u8; 3] {
        let h = d.x.atan2(d.y);
        let e = d.z.asin();
        let f = |a: f32| ((a.sin() * 0.5 + 0.5) * 255.0) as u8;
        [f(7.0 * h + 3.0 * e), f(5.0 * e - 4.0 * h + 1.0), f(11.0 * h * e.cos() + 2.0)]
    }

    fn render(camera: &Pinhole, pose: Quat) -> Rgba8Image {
        super::super::reproject::render_synthetic(camera, pose, &world)
    }

    /// (heading, pitch) in degrees: eight shots around the horizon and two at 40° pitch.
    const TEN_AIMS: [(f64, f64); 10] = [
        (0.0, 0.0),
        (45.0, 0.0),
        (90.0, 0.0),
        (135.0, 0.0),
        (180.0, 0.0),
        (225.0, 0.0),
        (270.0, 0.0),
        (315.0, 0.0),
        (20.0, 40.0),
        (60.0, 40.0),
    ];

    #[test]
    fn heading_errors_between_shots_are_recovered_from_the_overlaps() {
        let cam = Pinhole::from_vfov(160, 120, 50.0).unwrap();
        // Eight shots around the horizon and two at ±45° pitch; the images are taken at the true
        // poses, the "estimated" poses carry heading errors of up to 3.5° (the front's is the
        // reference and stays).
        let aims = TEN_AIMS;
        let errors = [0.0, 2.0, -3.5, 1.0, 3.0, -2.5, 0.5, -1.5, 2.5, -3.0];
        let shots: Vec<Shot> = aims
            .iter()
            .zip(errors)
            .enumerate()
            .map(|(i, (&(h, p), e)): (usize, (&(f64, f64), f64))| {
                let truth = from_heading_pitch_roll(h.to_radians(), p.to_radians(), 0.02).as_quat();
                let estimate = (Quat::from_rotation_z((e as f32).to_radians()) * truth).normalize();
                Shot { target: i, t: i as f64, pose: estimate, image: Arc::new(render(&cam, truth)), gravity: None }
            })
            .collect();
        let (aligned, report) = align_shots(&cam, &shots, 0);
        assert!(report.pairs.len() >= 9, "{report:?}");
        for (i, (s, e)) in aligned.iter().zip(errors).enumerate() {
            let truth = from_heading_pitch_roll(aims[i].0.to_radians(), aims[i].1.to_radians(), 0.02).as_quat();
            let residual = s.pose.angle_between(truth).to_degrees();
            // Before: |e| up to 3.5°; after: under 0.2°.
            assert!(residual < 0.2, "shot {i}: error {e}° -> {residual:.3}°");
        }
        // A featureless world cannot be matched: nothing moves.
        let flat = Arc::new(Rgba8Image { width: 160, height: 120, pixels: vec![100; 160 * 120 * 4] });
        let flat_shots: Vec<Shot> = shots.iter().map(|s| Shot { image: flat.clone(), ..s.clone() }).collect();
        let (same, report) = align_shots(&cam, &flat_shots, 0);
        assert!(report.pairs.is_empty());
        assert!(same.iter().zip(&flat_shots).all(|(a, b)| a.pose == b.pose));
    }

    #[test]
    fn tilt_errors_between_shots_are_refined_away_jointly() {
        let cam = Pinhole::from_vfov(160, 120, 50.0).unwrap();
        // The same ten shots, each estimate off by a heading error and a tilt error (world x
        // and y turns, up to 0.8°, summing to zero over the shots: the accelerometer's tilt
        // errs per shot, the capture's vertical is their mean).
        let aims = TEN_AIMS;
        let yaw = [0.0, 1.0, -1.5, 0.5, 1.5, -1.0, 0.5, -0.5, 1.0, -1.0];
        let tilt = [
            (0.4, -0.3),
            (-0.6, 0.2),
            (0.3, 0.5),
            (-0.2, -0.8),
            (0.7, 0.1),
            (-0.5, 0.4),
            (0.2, -0.2),
            (-0.4, 0.6),
            (0.6, -0.3),
            (-0.5, -0.2),
        ];
        let truths: Vec<Quat> =
            aims.iter().map(|&(h, p): &(f64, f64)| from_heading_pitch_roll(h.to_radians(), p.to_radians(), 0.02).as_quat()).collect();
        let shots: Vec<Shot> = truths
            .iter()
            .enumerate()
            .map(|(i, truth)| {
                let (tx, ty) = tilt[i];
                let error =
                    turn(yaw[i]) * Quat::from_rotation_x((tx as f32).to_radians()) * Quat::from_rotation_y((ty as f32).to_radians());
                Shot { target: i, t: i as f64, pose: (error * *truth).normalize(), image: Arc::new(render(&cam, *truth)), gravity: None }
            })
            .collect();
        let worst = |s: &[Shot]| s.iter().zip(&truths).map(|(s, t)| s.pose.angle_between(*t).to_degrees()).fold(0.0, f32::max);
        let before = worst(&shots);
        let (turned, _) = align_turns(&cam, &shots, 0);
        let (refined, report) = align_shots(&cam, &shots, 0);
        let (after_turns, after) = (worst(&turned), worst(&refined));
        eprintln!("worst shot error: {before:.3}° as taken, {after_turns:.3}° after the turns, {after:.3}° refined ({report:?})");
        // The turns cannot take tilt off; the joint refinement takes both to a small fraction
        // of a pixel (0.42° here).
        assert!(after_turns > 0.5, "{after_turns}");
        assert!(after < 0.1, "{after}");
        assert!(report.refinement.rms_after < report.refinement.rms_before);
        // The front keeps its heading (the turn of its refinement about the vertical is ~0).
        assert!(report.turns_deg[0].abs() < 0.05, "{:?}", report.turns_deg);
    }

    #[test]
    fn a_tilt_common_to_all_shots_is_taken_off_by_their_held_gravity() {
        use crate::capture::gravity::HeldGravity;
        let cam = Pinhole::from_vfov(160, 120, 50.0).unwrap();
        // Every estimate tilted alike by 0.4° (the images cannot see it); each shot held still,
        // its accelerometer reading gravity in its true frame.
        let common = Quat::from_axis_angle(Vec3::new(1.0, 1.0, 0.0).normalize(), 0.4f32.to_radians());
        let truths: Vec<Quat> =
            TEN_AIMS.iter().map(|&(h, p): &(f64, f64)| from_heading_pitch_roll(h.to_radians(), p.to_radians(), 0.02).as_quat()).collect();
        let shots = |gravity: bool| -> Vec<Shot> {
            truths
                .iter()
                .enumerate()
                .map(|(i, truth)| {
                    let up = truth.as_dquat().inverse() * glam::DVec3::Z * crate::sensors::STANDARD_GRAVITY;
                    let held = HeldGravity { accel: up, lever: glam::DMat3::ZERO, gyro: glam::DMat3::ZERO };
                    Shot {
                        target: i,
                        t: i as f64,
                        pose: (common * *truth).normalize(),
                        image: Arc::new(render(&cam, *truth)),
                        gravity: gravity.then_some(held),
                    }
                })
                .collect()
        };
        let worst = |s: &[Shot]| s.iter().zip(&truths).map(|(s, t)| s.pose.angle_between(*t).to_degrees()).fold(0.0, f32::max);
        let (without, report) = align_shots(&cam, &shots(false), 0);
        assert!(report.leveling.is_none());
        let (with, report) = align_shots(&cam, &shots(true), 0);
        let (before, after) = (worst(&without), worst(&with));
        eprintln!("worst shot error: {before:.3}° without the held gravity, {after:.3}° with ({:?})", report.leveling);
        assert!(before > 0.3, "{before}");
        assert!(after < 0.05, "{after}");
        assert_eq!(report.leveling.map(|l| l.shots), Some(10));
    }

    #[test]
    fn a_new_shot_is_turned_by_its_heading_drift_against_the_earlier_shots() {
        let cam = Pinhole::from_vfov(160, 120, 50.0).unwrap();
        let shot = |i: usize, h: f64, p: f64, drift: f32| {
            let truth = from_heading_pitch_roll(h.to_radians(), p.to_radians(), 0.0).as_quat();
            // The guidance's pose: heading drifted clockwise by `drift` (a turn by −drift).
            let estimate = (Quat::from_rotation_z(-drift.to_radians()) * truth).normalize();
            Shot { target: i, t: i as f64, pose: estimate, image: Arc::new(render(&cam, truth)), gravity: None }
        };
        let earlier = [shot(0, 0.0, 0.0, 0.0), shot(1, 120.0, 0.0, 0.0)];
        // 30° to the right of the front, 2.5° of drift: the turn that takes it off is +2.5°,
        // found against the front (the shot 120° away does not overlap).
        let (against, turn) = turn_against(&cam, &earlier, &shot(2, 30.0, 0.0, 2.5)).unwrap();
        assert!(against == 0 && (turn - 2.5).abs() < 0.1, "{against} {turn}");
        let (against, turn) = turn_against(&cam, &earlier, &shot(2, 95.0, 5.0, -4.0)).unwrap();
        assert!(against == 1 && (turn + 4.0).abs() < 0.1, "{against} {turn}");
        // Nothing overlaps the back: no measurement.
        assert_eq!(turn_against(&cam, &earlier, &shot(2, 240.0, 0.0, 1.0)), None);
        // The new shot's pose also tilted by 2.5° (the held filter's tilt error at `bad` noise):
        // the turn is still found, where a search of the turn alone errs.
        let tilted = |drift: f32| {
            let s = shot(2, 10.0, 30.0, drift);
            Shot { pose: (Quat::from_rotation_x(2.5f32.to_radians()) * s.pose).normalize(), ..s }
        };
        let (_, turn) = turn_against(&cam, &earlier, &tilted(2.0)).unwrap();
        assert!((turn - 2.0).abs() < 0.3, "{turn}");
        let (yaw_only, _) = match_pair(&cam, &earlier[0], &tilted(2.0)).unwrap();
        eprintln!("tilted 2.5 deg, drift 2 deg: turn found {turn:.2}, by the turn alone {yaw_only:.2}");
    }

    #[test]
    fn joint_solve_reference_values() {
        // Three shots in a chain with consistent relative turns: 0 → 1: +1°, 1 → 2: +2°, 0 → 2: +3°.
        let p = |i, j, d| PairMatch { i, j, delta_deg: d, samples: 1_000_000 };
        let h = solve(3, 0, &[p(0, 1, 1.0), p(1, 2, 2.0), p(0, 2, 3.0)]);
        assert!(h[0] == 0.0 && (h[1] - 1.0).abs() < 1e-4 && (h[2] - 3.0).abs() < 1e-4, "{h:?}");
        // No pairs: every turn stays 0 (the sensor pose).
        assert_eq!(solve(3, 1, &[]), vec![0.0; 3]);
    }
}
