//! `report.html`: one self-contained page (no network, no CDN) that shows a
//! fit and its map: the summary from the typed report, the reference and the
//! aligned SLAM path in 3-D coloured by the per-pose error, `p_k` with the
//! start-up stages, the error over time and its histogram, and the world
//! cloud with the occupied octree voxels in an interactive 3-D view.
//!
//! The page is made here, in Rust, so that the command line needs no Python.
//! Its script (`page.js`, a small WebGL 2 viewer and canvas plots) and style
//! (`page.css`) are compiled in with `include_str!`; the data it draws is one
//! JSON block ([`PageData`]: the report and the [`FigureData`], large arrays
//! as base64 little-endian bytes). The summary is plain HTML written here, so
//! it reads without the script; every number taken from the report carries
//! `data-doc`, `data-key` (its JSON path in that document, e.g.
//! `ape.rmse`) and `data-value` (the number as the JSON has it), and every
//! number computed for the page (gravity in SLAM axes, rotation angle)
//! carries `data-derived` instead.

use std::fmt::Write as _;
use std::path::Path;

use serde::Serialize;

use super::figures::FigureData;
use super::report::{
    AlignReport, ApeReport, DemoReport, FitReport, GnssReport, ImuReport, OctreeReport,
    PriorReport, Report, TransformReport, WindowedReport,
};
use crate::error::{Error, Result};

/// The page's script: the WebGL viewer and the 2-D plots.
const PAGE_JS: &str = include_str!("page.js");
/// The page's style.
const PAGE_CSS: &str = include_str!("page.css");

/// The report a page summarises.
#[derive(Clone, Copy, Debug, Serialize)]
#[serde(untagged)]
pub enum Summary<'a> {
    /// `convert` (and `demo`): `report.json`.
    Convert(&'a Report),
    /// `align --html`: what `align --json` prints.
    Align(&'a AlignReport),
}

impl Summary<'_> {
    /// The `data-doc` name of the report's numbers.
    fn doc(&self) -> &'static str {
        match self {
            Summary::Convert(_) => "report",
            Summary::Align(_) => "align",
        }
    }
}

/// One page.
#[derive(Clone, Copy, Debug)]
pub struct Page<'a> {
    /// The title (the input's name, say).
    pub title: &'a str,
    /// The report summarised.
    pub summary: Summary<'a>,
    /// The demo's comparison with the truth, for `demo`.
    pub demo: Option<&'a DemoReport>,
    /// What the figures draw.
    pub figures: &'a FigureData,
}

/// The JSON block embedded in the page (read by `page.js`).
#[derive(Serialize)]
pub struct PageData<'a> {
    /// `"report"` or `"align"`.
    pub kind: &'static str,
    /// The report, as its JSON document holds it.
    pub report: Summary<'a>,
    /// The demo report, for `demo`.
    pub demo: Option<&'a DemoReport>,
    /// The figures.
    pub figures: &'a FigureData,
}

/// Text with `<`, `>`, `&` and quotes escaped.
fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '&' => out.push_str("&amp;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// `v` with `sig` significant digits (exponent form outside 1e-4 … 1e7).
pub fn format_number(v: f64, sig: usize) -> String {
    if !v.is_finite() {
        return "—".into();
    }
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-4..1e7).contains(&a) {
        return format!("{:.*e}", sig.saturating_sub(1), v);
    }
    let mag = a.log10().floor() as i64;
    let decimals = (sig as i64 - 1 - mag).max(0) as usize;
    format!("{v:.decimals$}")
}

/// The JSON text of a number, as `serde_json` writes it (`null` when not finite).
fn json_number(v: f64) -> String {
    serde_json::to_string(&v).unwrap_or_else(|_| "null".into())
}

/// Rows of one card of the summary.
struct Card {
    doc: &'static str,
    title: String,
    note: String,
    rows: Vec<(String, String)>,
}

impl Card {
    fn new(doc: &'static str, title: &str) -> Self {
        Card {
            doc,
            title: title.into(),
            note: String::new(),
            rows: Vec::new(),
        }
    }

    /// A number of the report at JSON path `key`.
    fn num(&self, key: &str, v: f64, sig: usize) -> String {
        format!(
            "<span class=\"num\" data-doc=\"{}\" data-key=\"{}\" data-value=\"{}\">{}</span>",
            self.doc,
            esc(key),
            json_number(v),
            format_number(v, sig)
        )
    }

    /// A count of the report at JSON path `key`.
    fn count(&self, key: &str, v: usize) -> String {
        format!(
            "<span class=\"num\" data-doc=\"{}\" data-key=\"{}\" data-value=\"{v}\">{v}</span>",
            self.doc,
            esc(key)
        )
    }

    /// The length of the array at JSON path `key`.
    fn length(&self, key: &str, v: usize) -> String {
        format!(
            "<span class=\"num\" data-doc=\"{}\" data-key=\"{}\" data-len=\"{v}\">{v}</span>",
            self.doc,
            esc(key)
        )
    }

    /// Numbers at `key.0`, `key.1`, … in brackets.
    fn nums(&self, key: &str, v: &[f64], sig: usize) -> String {
        let parts: Vec<String> = v
            .iter()
            .enumerate()
            .map(|(i, x)| self.num(&format!("{key}.{i}"), *x, sig))
            .collect();
        format!("[{}]", parts.join(", "))
    }

    fn row(&mut self, label: &str, value: String) {
        self.rows.push((esc(label), value));
    }

    fn html(&self) -> String {
        let mut s = format!(
            "<section class=\"card\"><h3>{}</h3><table>",
            esc(&self.title)
        );
        for (k, v) in &self.rows {
            let _ = write!(s, "<tr><th>{k}</th><td>{v}</td></tr>");
        }
        s += "</table>";
        if !self.note.is_empty() {
            let _ = write!(s, "<p class=\"note\">{}</p>", self.note);
        }
        s += "</section>";
        s
    }
}

/// A number computed for the page (not in the report), named `name`.
fn derived(name: &str, v: f64, sig: usize) -> String {
    format!(
        "<span class=\"num derived\" data-derived=\"{}\" data-value=\"{}\">{}</span>",
        esc(name),
        json_number(v),
        format_number(v, sig)
    )
}

/// A count computed for the page (not in the report), named `name`.
fn derived_count(name: &str, v: usize) -> String {
    format!(
        "<span class=\"num derived\" data-derived=\"{}\" data-value=\"{v}\">{v}</span>",
        esc(name)
    )
}

/// Gravity's direction in SLAM axes, `R_world_slamᵀ · (0, 0, −1)`, and the
/// rotation angle in degrees, from the report's matrix.
fn gravity_and_angle(t: &TransformReport) -> ([f64; 3], f64) {
    let m = t.matrix;
    let s = t.scale;
    // Column z of R is R·e_z; row 2 of R is Rᵀ·e_z.
    let g = if s > 0.0 {
        [-m[2][0] / s, -m[2][1] / s, -m[2][2] / s]
    } else {
        [f64::NAN; 3]
    };
    let w = t.quaternion_xyzw[3].abs().min(1.0);
    (g, 2.0 * w.acos().to_degrees())
}

/// The transform's card; `key` is the JSON path of the transform's fields
/// (empty: at the top level of the document).
fn transform_card(doc: &'static str, key: &str, t: &TransformReport, title: &str) -> Card {
    let mut c = Card::new(doc, title);
    let k = |f: &str| {
        if key.is_empty() {
            f.to_string()
        } else {
            format!("{key}.{f}")
        }
    };
    c.row("scale (m per SLAM unit)", c.num(&k("scale"), t.scale, 7));
    let (g, angle) = gravity_and_angle(t);
    c.row(
        "rotation",
        format!(
            "{}° about an axis; quaternion (x, y, z, w) {}",
            derived("rotation_angle_deg", angle, 5),
            c.nums(&k("quaternion_xyzw"), &t.quaternion_xyzw, 6)
        ),
    );
    c.row(
        "translation (m)",
        c.nums(&k("translation"), &t.translation, 6),
    );
    c.row(
        "gravity in SLAM axes",
        format!(
            "[{}, {}, {}] (unit; world −z seen from the SLAM frame)",
            derived("gravity_slam.0", g[0], 5),
            derived("gravity_slam.1", g[1], 5),
            derived("gravity_slam.2", g[2], 5)
        ),
    );
    c
}

fn ape_rows(c: &mut Card, key: &str, fit_rmse: Option<(String, f64)>, a: &ApeReport) {
    if let Some((k, v)) = fit_rmse {
        c.row("fit rmse (m, fitted pairs)", c.num(&k, v, 5));
    }
    let k = |f: &str| format!("{key}.{f}");
    c.row(
        "APE (m, every pair)",
        format!(
            "rmse {} · mean {} · median {} · std {} · min {} · max {}",
            c.num(&k("rmse"), a.rmse, 5),
            c.num(&k("mean"), a.mean, 5),
            c.num(&k("median"), a.median, 5),
            c.num(&k("std"), a.std, 5),
            c.num(&k("min"), a.min, 5),
            c.num(&k("max"), a.max, 5)
        ),
    );
    c.row("APE pairs", c.count(&k("n_pairs"), a.n_pairs));
}

/// The start-up cut, the robust fit, the offset search and the intervals.
fn fit_cards(doc: &'static str, f: &FitReport, figures: &FigureData) -> Vec<Card> {
    let mut cards = Vec::new();
    let mut c = Card::new(doc, "Start-up stages");
    match &f.stages {
        Some(s) => {
            let k = |n: &str| format!("fit.stages.{n}");
            c.row(
                "converging from p_k",
                c.count(&k("converging_start"), s.converging_start),
            );
            c.row(
                "stable from p_k",
                c.count(&k("stable_start"), s.stable_start),
            );
            c.row("factors", c.count(&k("n_factors"), s.n_factors));
            c.row(
                "stable level (≈ s²)",
                c.num(&k("stable_level"), s.stable_level, 6),
            );
            c.row("noise of ln p_k", c.num(&k("noise"), s.noise, 4));
            c.note = "Detected in the scale factors and cut from the fit (skip_init auto).".into();
        }
        None => match &figures.stages {
            Some(s) => {
                let st = &s.stages;
                c.row(
                    "converging from p_k",
                    derived_count("stages.converging_start", st.converging_start),
                );
                c.row(
                    "stable from p_k",
                    derived_count("stages.stable_start", st.stable_start),
                );
                c.row(
                    "stable level (≈ s²)",
                    derived("stages.stable_level", st.stable_level, 6),
                );
                c.note = "Detected for this page only: the fit did not cut them (skip_init was not auto).".into();
            }
            None => c.note = "No start-up stages found (too few pairs, or none asked for).".into(),
        },
    }
    c.row("first fitted pair", c.count("fit.fit_start", f.fit_start));
    c.row("pairs before it dropped because", esc(&f.skip_reason));
    c.row(
        "seconds added to SLAM stamps",
        c.num("fit.offset", f.offset, 6),
    );
    if let (Some(i), Some(o)) = (f.n_inliers, f.n_outliers) {
        c.row(
            "robust fit",
            format!(
                "{} inliers, {} outliers (dropped)",
                c.count("fit.n_inliers", i),
                c.count("fit.n_outliers", o)
            ),
        );
    }
    if let Some(o) = &f.offset_estimate {
        c.row(
            "time offset estimated (s)",
            format!(
                "{} (rmse {} m, {} m at zero, {} poses)",
                c.num("fit.offset_estimate.estimated", o.estimated, 6),
                c.num("fit.offset_estimate.rmse", o.rmse, 5),
                c.num("fit.offset_estimate.rmse_at_zero", o.rmse_at_zero, 5),
                c.count("fit.offset_estimate.n_used", o.n_used)
            ),
        );
    }
    cards.push(c);
    if let Some(i) = &f.intervals {
        let mut c = Card::new(doc, "Confidence intervals");
        c.row("level", c.num("fit.intervals.level", i.level, 4));
        c.row("scale", c.nums("fit.intervals.scale", &i.scale, 7));
        for (a, name) in ["x", "y", "z"].iter().enumerate() {
            c.row(
                &format!("translation {name} (m)"),
                c.nums(
                    &format!("fit.intervals.translation.{a}"),
                    &i.translation[a],
                    6,
                ),
            );
        }
        c.row(
            "rotation ± about x, y, z (deg)",
            c.nums(
                "fit.intervals.rotation_half_width_deg",
                &i.rotation_half_width_deg,
                4,
            ),
        );
        c.row(
            "residual σ per axis (m)",
            c.num("fit.intervals.sigma", i.sigma, 5),
        );
        cards.push(c);
    }
    cards
}

fn imu_card(doc: &'static str, r: &ImuReport) -> Card {
    let mut c = Card::new(doc, "Inertial initialisation");
    c.row(
        "gives T_world_slam",
        if r.used_for_transform {
            "yes"
        } else {
            "no (checked against the poses)"
        }
        .into(),
    );
    if let Some(e) = &r.error {
        c.row("failed", esc(e));
        return c;
    }
    if let Some(s) = r.scale {
        c.row(
            "scale ± σ",
            format!(
                "{} ± {}",
                c.num("imu.scale.0", s[0], 7),
                c.num("imu.scale.1", s[1], 3)
            ),
        );
    }
    if let Some(g) = r.gravity_slam {
        c.row(
            "gravity in SLAM axes (m/s²)",
            c.nums("imu.gravity_slam", &g, 5),
        );
    }
    if let Some(g) = r.gravity_sigma_deg {
        c.row(
            "gravity direction σ (deg)",
            c.num("imu.gravity_sigma_deg", g, 4),
        );
    }
    if let Some(p) = &r.pose_check {
        c.row(
            "against the pose fit",
            format!(
                "scale {} (relative), gravity {}°",
                c.num("imu.pose_check.scale_difference", p.scale_difference, 4),
                c.num("imu.pose_check.gravity_angle_deg", p.gravity_angle_deg, 4)
            ),
        );
    }
    c
}

/// Metric scale and "up" with no second sensor: what set them, the ground
/// plane, the heights, the known distance, the cameras' plane.
fn prior_card(doc: &'static str, r: &PriorReport) -> Card {
    let mut c = Card::new(doc, "No second sensor: the prior");
    c.row(
        "gives T_world_slam",
        if r.used_for_transform {
            "yes"
        } else {
            "no (compared with the sensor)"
        }
        .into(),
    );
    c.row(
        "scale from",
        format!(
            "{} ({})",
            esc(&r.scale_from.replace('_', " ")),
            c.num("prior.scale", r.scale, 7)
        ),
    );
    c.row("up from", esc(&r.up_from.replace('_', " ")));
    if let Some(p) = &r.plane {
        c.row(
            "ground plane",
            format!(
                "{} of {} points, spread {} units",
                c.count("prior.plane.inliers", p.inliers),
                c.count("prior.plane.n_points", p.n_points),
                c.num("prior.plane.spread", p.spread, 3)
            ),
        );
        if let Some(t) = p.tilt_from_cameras_deg {
            c.row(
                "normal from the cameras' up (deg)",
                c.num("prior.plane.tilt_from_cameras_deg", t, 3),
            );
        }
        c.row(
            "normal's sigma (deg)",
            c.num("prior.plane.tilt_sigma_deg", p.tilt_sigma_deg, 3),
        );
    }
    if let (Some(h), Some(rms)) = (r.height_scale, r.height_rms) {
        c.row(
            "scale from the heights",
            format!(
                "{} (heights rms {} m)",
                c.num("prior.height_scale", h, 7),
                c.num("prior.height_rms", rms, 3)
            ),
        );
    }
    if let (Some(s), Some(g)) = (r.scale_sigma, r.scale_sigma_ground) {
        c.row(
            "scale's sigma (relative)",
            format!(
                "{} (ground plane and heights' scatter {}{})",
                c.num("prior.scale_sigma", s, 3),
                c.num("prior.scale_sigma_ground", g, 3),
                match r.camera_height_sigma {
                    Some(m) => format!(", height ± {} m", c.num("prior.camera_height_sigma", m, 3)),
                    None => String::new(),
                }
            ),
        );
    }
    if let Some(d) = &r.known_distance {
        let end = |k: usize| match d.poses[k] {
            Some(i) => format!(
                "pose {}",
                c.count(&format!("prior.known_distance.poses.{k}"), i)
            ),
            None => format!(
                "map point {}",
                c.nums(&format!("prior.known_distance.ends.{k}"), &d.ends[k], 6)
            ),
        };
        c.row(
            "known distance",
            format!(
                "{} and {}: {} m over {} units",
                end(0),
                end(1),
                c.num("prior.known_distance.metres", d.metres, 6),
                c.num("prior.known_distance.slam_distance", d.slam_distance, 6)
            ),
        );
    }
    if let Some(m) = &r.planar_motion {
        c.row(
            "cameras' plane",
            format!(
                "rms {} units off it, tilt bound {}°",
                c.num("prior.planar_motion.rms", m.rms, 3),
                c.num("prior.planar_motion.tilt_bound_deg", m.tilt_bound_deg, 3)
            ),
        );
    }
    if let (Some(ds), Some(up)) = (r.scale_vs_sensor, r.up_vs_sensor_deg) {
        c.row(
            "against the sensor",
            format!(
                "scale {} (relative), up {}°",
                c.num("prior.scale_vs_sensor", ds, 4),
                c.num("prior.up_vs_sensor_deg", up, 4)
            ),
        );
    }
    c
}

/// The GNSS reference: the ENU origin the world is, its UTM zone, the fixes.
fn gnss_card(doc: &'static str, g: &GnssReport) -> Card {
    let mut c = Card::new(doc, "GNSS reference (world = ENU)");
    c.row(
        "ENU origin (lat °, lon °, alt m)",
        format!(
            "{}, {}, {} ({})",
            c.num("gnss.origin.0", g.origin[0], 10),
            c.num("gnss.origin.1", g.origin[1], 10),
            c.num("gnss.origin.2", g.origin[2], 7),
            esc(&g.origin_rule)
        ),
    );
    if let (Some(z), Some(e)) = (&g.utm_zone, g.utm_epsg) {
        c.row("UTM zone", format!("{} (EPSG:{e})", esc(z)));
    }
    c.row(
        "fixes",
        format!(
            "{} kept, {} without a fix dropped",
            c.count("gnss.fixes", g.fixes),
            c.count("gnss.dropped_no_fix", g.dropped_no_fix)
        ),
    );
    c.note = if doc == "align" {
        "x east, y north, z up (metres); T_ref_est is T_enu_est."
    } else {
        "x east, y north, z up (metres); T_world_slam is T_enu_slam."
    }
    .into();
    c
}

fn octree_card(doc: &'static str, o: &OctreeReport, figures: &FigureData) -> Card {
    let mut c = Card::new(doc, "Occupancy octree");
    c.row(
        "resolution (m)",
        c.num("octree.resolution", o.resolution, 6),
    );
    c.row(
        "occupied leaves",
        c.count("octree.leaves_occupied", o.leaves_occupied),
    );
    c.row("free leaves", c.count("octree.leaves_free", o.leaves_free));
    c.row("nodes", c.count("octree.nodes", o.nodes));
    c.row(
        "scans / points inserted",
        format!(
            "{} / {}",
            c.count("octree.scans", o.scans),
            c.count("octree.points", o.points)
        ),
    );
    if let Some(v) = &figures.voxels {
        c.note = if v.n == v.n_total {
            format!("All {} occupied leaves are drawn.", v.n)
        } else {
            format!(
                "{} occupied leaves drawn as {} cubes of {} m and more (merged to stay within the page's limit).",
                v.n_total,
                v.n,
                format_number(v.shown_resolution, 4)
            )
        };
    }
    c
}

fn windowed_card(doc: &'static str, w: &WindowedReport) -> Card {
    let mut c = Card::new(doc, "Windowed fit (scale drift)");
    c.row("window", esc(&w.window));
    c.row("cloud carried by", esc(&w.cloud));
    c.row(
        "rmse windowed / single (m)",
        format!(
            "{} / {}",
            c.num("windowed.windowed_rmse", w.windowed_rmse, 5),
            c.num("windowed.single_rmse", w.single_rmse, 5)
        ),
    );
    c.row(
        "local scale range",
        format!(
            "[{}, {}]",
            c.num("windowed.scale_min", w.scale_min, 6),
            c.num("windowed.scale_max", w.scale_max, 6)
        ),
    );
    c
}

fn demo_card(d: &DemoReport) -> Card {
    let mut c = Card::new("demo", "Against the truth (demo)");
    c.row("true scale", c.num("truth.scale", d.truth.scale, 7));
    let e = &d.transform_error;
    c.row(
        "scale error (relative)",
        c.num("transform_error.scale_error", e.scale_error, 4),
    );
    c.row(
        "rotation / gravity error (deg)",
        format!(
            "{} / {}",
            c.num(
                "transform_error.rotation_error_deg",
                e.rotation_error_deg,
                4
            ),
            c.num("transform_error.gravity_error_deg", e.gravity_error_deg, 4)
        ),
    );
    c.row(
        "translation error (m)",
        c.num("transform_error.translation_error", e.translation_error, 4),
    );
    let ce = &d.cloud_error;
    c.row(
        "cloud to true surfaces (m)",
        format!(
            "median {} · rmse {} · p95 {}",
            c.num("cloud_error.median", ce.median, 4),
            c.num("cloud_error.rmse", ce.rmse, 4),
            c.num("cloud_error.p95", ce.p95, 4)
        ),
    );
    let ct = &d.cloud_error_true_transform;
    c.row(
        "the same, true transform (m)",
        format!(
            "median {} · rmse {}",
            c.num("cloud_error_true_transform.median", ct.median, 4),
            c.num("cloud_error_true_transform.rmse", ct.rmse, 4)
        ),
    );
    c.row(
        "keyframe APE vs true path (m)",
        c.num("ape_keyframes.rmse", d.ape_keyframes.rmse, 4),
    );
    c.row(
        "true stages (frames)",
        format!(
            "converging from {}, stable from {}",
            c.count("stages.converge_start", d.stages.converge_start),
            c.count("stages.stable_start", d.stages.stable_start)
        ),
    );
    c
}

fn convert_cards(r: &Report, figures: &FigureData) -> Vec<Card> {
    let doc = "report";
    let mut cards = Vec::new();
    let mut t = transform_card(doc, "t_world_slam", &r.t_world_slam, "T_world_slam");
    if let Some(a) = &r.ape {
        ape_rows(
            &mut t,
            "ape",
            r.fit_rmse.map(|v| ("fit_rmse".to_string(), v)),
            a,
        );
    }
    cards.push(t);

    let mut p = Card::new(doc, "Pairs");
    p.row("SLAM poses (keyframes)", p.count("keyframes", r.keyframes));
    p.row(
        "reference poses",
        p.count("reference_poses", r.reference_poses),
    );
    p.row(
        "matched with a reference pose",
        p.count("frames_used", r.frames_used),
    );
    p.row(
        "dropped: no reference pose within max_diff",
        format!(
            "{} (max_diff {} s, offset {} s)",
            p.length("frames_dropped", r.frames_dropped.len()),
            p.num("max_diff", r.max_diff, 6),
            p.num("offset", r.offset, 6)
        ),
    );
    p.row("pairs fitted", p.count("pairs_fitted", r.pairs_fitted));
    p.row(
        "pairs not fitted",
        format!(
            "{} of {} (start-up cut, n_to_align, robust outliers)",
            derived_count(
                "pairs_not_fitted",
                r.pairs.len() - r.pairs_fitted.min(r.pairs.len())
            ),
            p.length("pairs", r.pairs.len())
        ),
    );
    cards.push(p);
    if let Some(f) = &r.fit {
        cards.extend(fit_cards(doc, f, figures));
    }
    if let Some(i) = &r.imu {
        cards.push(imu_card(doc, i));
    }
    if let Some(p) = &r.prior {
        cards.push(prior_card(doc, p));
    }
    if let Some(w) = &r.windowed {
        cards.push(windowed_card(doc, w));
    }
    if let Some(o) = &r.octree {
        cards.push(octree_card(doc, o, figures));
    }
    if let Some(g) = &r.gnss {
        cards.push(gnss_card(doc, g));
    }
    let mut i = Card::new(doc, "Input");
    i.row("file", esc(&r.input.display().to_string()));
    i.row("format", esc(&r.format));
    for (label, v) in [
        ("keyframe topic", &r.keyframe_topic),
        ("graph topic", &r.graph_topic),
        ("reference topic", &r.reference_topic),
    ] {
        if let Some(v) = v {
            i.row(label, esc(v));
        }
    }
    i.row("world cloud points", i.count("points", r.points));
    if let Some(c) = &figures.cloud {
        i.note = if c.stride > 1 {
            format!(
                "The 3-D view draws every {}th point ({} of {}).",
                c.stride, c.n, c.n_total
            )
        } else {
            format!("The 3-D view draws all {} points.", c.n)
        };
    }
    cards.push(i);
    cards
}

fn align_cards(r: &AlignReport, figures: &FigureData) -> Vec<Card> {
    let doc = "align";
    let tr = TransformReport {
        quaternion_xyzw: r.quaternion_xyzw,
        translation: r.translation,
        scale: r.scale,
        matrix: std::array::from_fn(|i| {
            std::array::from_fn(|j| match (i, j) {
                (3, 3) => 1.0,
                (3, _) => 0.0,
                (_, 3) => r.translation[i],
                _ => r.scale * r.rotation[i][j],
            })
        }),
    };
    let mut t = transform_card(
        doc,
        "",
        &tr,
        if r.with_scale {
            "T_ref_est, Sim(3)"
        } else {
            "T_ref_est, SE(3)"
        },
    );
    ape_rows(&mut t, "ape", Some(("fit_rmse".into(), r.fit_rmse)), &r.ape);
    let mut cards = vec![t];
    let mut p = Card::new(doc, "Pairs");
    p.row("EST poses", p.count("n_est", r.n_est));
    p.row("REF poses", p.count("n_ref", r.n_ref));
    p.row(
        "matched",
        format!(
            "{} (max_diff {} s, offset {} s)",
            p.count("n_pairs", r.n_pairs),
            p.num("max_diff", r.max_diff, 6),
            p.num("offset", r.offset, 6)
        ),
    );
    p.row("fitted", p.count("n_fitted", r.n_fitted));
    if let Some(u) = &r.time_units {
        let how = |found: bool| {
            if found {
                "found from the stamps"
            } else {
                "given"
            }
        };
        p.row(
            "stamps read in",
            format!(
                "EST {} ({}), REF {} ({})",
                esc(&u.est),
                how(u.est_detected),
                esc(&u.reference),
                how(u.ref_detected)
            ),
        );
    }
    p.row(
        "EST poses without a REF pose within max_diff",
        derived_count("est_unmatched", r.n_est - r.n_pairs.min(r.n_est)),
    );
    p.row("estimate", esc(&r.est));
    p.row("reference", esc(&r.reference));
    cards.push(p);
    if let Some(g) = &r.gnss {
        cards.push(gnss_card(doc, g));
    }
    cards.extend(fit_cards(doc, &r.fit, figures));
    cards
}

/// The page as HTML text.
pub fn render(page: &Page<'_>) -> Result<String> {
    let mut out = Vec::new();
    render_into(&mut out, page).map_err(|e| Error::invalid("report page", e.to_string()))?;
    String::from_utf8(out).map_err(|e| Error::invalid("report page", e.to_string()))
}

/// Inside `<script>`, `<` only occurs in JSON strings, where `\u003c` means
/// the same: the JSON passes through this on its way into the page, so the
/// page is written without a copy of the JSON text.
struct EscapeLt<'w>(&'w mut dyn std::io::Write);

impl std::io::Write for EscapeLt<'_> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let mut rest = buf;
        while let Some(i) = rest.iter().position(|&b| b == b'<') {
            self.0.write_all(&rest[..i])?;
            self.0.write_all(b"\\u003c")?;
            rest = &rest[i + 1..];
        }
        self.0.write_all(rest)?;
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.0.flush()
    }
}

/// Writes the page to `out` as it is made: the figures' JSON goes straight
/// from the data into the page (a page of several MB is never held whole,
/// nor its JSON).
pub fn render_into(out: &mut dyn std::io::Write, page: &Page<'_>) -> std::io::Result<()> {
    use std::io::Write as _;
    let cards = match page.summary {
        Summary::Convert(r) => convert_cards(r, page.figures),
        Summary::Align(r) => align_cards(r, page.figures),
    };
    let data = PageData {
        kind: page.summary.doc(),
        report: page.summary,
        demo: page.demo,
        figures: page.figures,
    };
    let mut html = String::with_capacity(64 * 1024);
    let title = esc(page.title);
    let _ = write!(
        html,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <meta name=\"generator\" content=\"slam2world {}\">\n\
         <title>slam2world report: {title}</title>\n<style>\n{PAGE_CSS}</style>\n</head>\n<body>\n",
        env!("CARGO_PKG_VERSION")
    );
    let _ = write!(
        html,
        "<header><h1>slam2world report</h1><p class=\"sub\">{title}</p>\
         <p id=\"s2w-status\" class=\"status\">drawing…</p></header>\n<main>\n\
         <div class=\"cards\" id=\"summary\">\n"
    );
    if let Some(d) = page.demo {
        html += &demo_card(d).html();
    }
    for c in &cards {
        html += &c.html();
        html.push('\n');
    }
    html += "</div>\n";
    html += FIGURES_HTML;
    let _ = write!(
        html,
        "</main>\n<footer>Written by slam2world {}; opens offline (everything it draws is in this file). \
         Units: metres, seconds; world frame z up.</footer>\n\
         <script id=\"s2w-data\" type=\"application/json\">",
        env!("CARGO_PKG_VERSION")
    );
    out.write_all(html.as_bytes())?;
    let mut json = std::io::BufWriter::with_capacity(64 * 1024, EscapeLt(out));
    serde_json::to_writer(&mut json, &data)?;
    json.flush()?;
    drop(json);
    write!(
        out,
        "</script>\n<script>\n{PAGE_JS}</script>\n</body>\n</html>\n"
    )
}

/// The figure sections (filled by `page.js`).
const FIGURES_HTML: &str = r#"<section class="figure" id="paths-section">
<h2>Paths in 3-D <small>reference grey, aligned SLAM coloured by the error of its pair</small></h2>
<div class="view"><canvas id="paths-view" class="gl" width="960" height="560"></canvas>
<div class="colorbar" id="paths-colorbar"></div></div>
<p class="hint">Drag to turn, shift-drag or right-drag to move, wheel to zoom, double-click to reset.</p>
</section>
<section class="figure" id="pk-section">
<h2>Scale factors p<sub>k</sub> <small>of consecutive matched pairs, with the start-up stages</small></h2>
<canvas id="pk-plot" class="plot" width="960" height="320"></canvas>
</section>
<section class="figure two" id="error-section">
<div><h2>Error over time</h2><canvas id="error-plot" class="plot" width="640" height="320"></canvas></div>
<div><h2>Error histogram</h2><canvas id="hist-plot" class="plot" width="480" height="320"></canvas></div>
</section>
<section class="figure" id="heights-section">
<h2>Camera heights over the ground <small>each SLAM pose's height over the ground plane, at the prior's scale</small></h2>
<canvas id="heights-plot" class="plot" width="960" height="280"></canvas>
</section>
<section class="figure" id="profile-section">
<h2>Scale along the run <small>the ground plane and the height per window of keyframes, against the run's one scale: <span id="profile-caption"></span></small></h2>
<canvas id="profile-plot" class="plot" width="960" height="280"></canvas>
</section>
<section class="figure" id="cloud-section">
<h2>World cloud <small id="cloud-caption"></small></h2>
<div class="controls">
<label>colour <select id="cloud-colour"><option value="height">by height</option><option value="image">by image colour</option></select></label>
<label><input type="checkbox" id="show-voxels"> occupied voxels</label>
<label><input type="checkbox" id="show-points" checked> points</label>
<label><input type="checkbox" id="show-paths" checked> paths</label>
<label><input type="checkbox" id="show-ground" checked> ground plane</label>
<label>point size <input type="range" id="point-size" min="1" max="6" value="2"></label>
</div>
<div class="view"><canvas id="cloud-view" class="gl" width="960" height="640"></canvas>
<div class="colorbar" id="cloud-colorbar"></div></div>
</section>
"#;

/// Writes the page to `path` (through a temporary file, renamed).
pub fn write_html(path: &Path, page: &Page<'_>) -> Result<()> {
    let mut set = crate::io::atomic::OutputSet::new();
    write_html_into(&mut set, path, page)?;
    set.commit().map(|_| ())
}

/// Writes the page to `path` as one output of `set`, as it is made.
pub fn write_html_into(
    set: &mut crate::io::atomic::OutputSet,
    path: &Path,
    page: &Page<'_>,
) -> Result<()> {
    use std::io::Write as _;
    set.write(path, |file| {
        let mut w = std::io::BufWriter::new(file);
        render_into(&mut w, page)
            .and_then(|_| w.flush())
            .map_err(|e| Error::io(path, e))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_keep_their_significant_digits() {
        assert_eq!(format_number(15.4901234, 6), "15.4901");
        assert_eq!(format_number(0.0123456, 3), "0.0123");
        assert_eq!(format_number(123456.0, 3), "123456");
        assert_eq!(format_number(1.5e-9, 3), "1.50e-9");
        assert_eq!(format_number(f64::NAN, 3), "—");
        assert_eq!(json_number(f64::NAN), "null");
        assert_eq!(json_number(0.1), "0.1");
    }

    #[test]
    fn text_is_escaped() {
        assert_eq!(
            esc("<a href=\"x\">&'"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&#39;"
        );
    }

    #[test]
    fn gravity_is_minus_z_in_slam_axes() {
        // A rotation of 90° about x maps SLAM y to world z: world −z is SLAM −y.
        let t = crate::geometry::Sim3::from_quaternion_xyzw(
            [
                std::f64::consts::FRAC_1_SQRT_2,
                0.0,
                0.0,
                std::f64::consts::FRAC_1_SQRT_2,
            ],
            nalgebra::Vector3::zeros(),
            2.0,
        )
        .unwrap();
        let (g, angle) = gravity_and_angle(&TransformReport::from(&t));
        assert!(
            (g[0]).abs() < 1e-12 && (g[1] + 1.0).abs() < 1e-12 && g[2].abs() < 1e-12,
            "{g:?}"
        );
        assert!((angle - 90.0).abs() < 1e-9);
    }
}
