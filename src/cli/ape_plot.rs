//! `align --plot`: evo_ape's two figures as PNG, drawn in Rust (plotters,
//! bitmap backend) so that the binary needs no Python and no system fonts
//! (text through `ab_glyph` with a subset of DejaVu Sans compiled in).
//!
//! - `<stem>_map.png`: the reference and the aligned estimate in the plane
//!   of most motion (the two world axes along which the reference spreads
//!   most), the estimate coloured by its APE;
//! - `<stem>_raw.png`: the APE over time with its mean, median and rmse, the
//!   mean ± std band shaded.
//!
//! Positions are metres in the reference frame; times seconds from the first
//! matched pair.

use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use plotters::prelude::*;
use plotters::style::FontStyle;

use crate::align::trajectories::TrajectoryAlignment;
use crate::error::{Error, Result};
use crate::trajectory::Trajectory;

/// Width of each figure, pixels.
pub const WIDTH: u32 = 1200;
/// Height of each figure, pixels.
pub const HEIGHT: u32 = 800;

/// DejaVu Sans (Bitstream Vera licence, `assets/DejaVuSans-LICENSE.txt`),
/// cut to Latin-1 and the few symbols the figures use.
static FONT: &[u8] = include_bytes!("assets/DejaVuSans-subset.ttf");

fn plot_error(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Io {
        path: path.to_path_buf(),
        source: std::io::Error::other(e.to_string()),
    }
}

/// Registers the font once (plotters keeps a process-wide table).
fn font() -> Result<()> {
    static ONCE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok = *ONCE.get_or_init(|| {
        plotters::style::register_font("sans-serif", FontStyle::Normal, FONT).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(Error::invalid("font", "the embedded font does not parse"))
    }
}

/// The two figure files of `save` (`ape.png` → `ape_map.png`, `ape_raw.png`).
pub fn figure_paths(save: &Path) -> (PathBuf, PathBuf) {
    let stem = save
        .file_stem()
        .map_or_else(|| "ape".into(), |s| s.to_string_lossy().into_owned());
    let dir = save.parent().unwrap_or(Path::new(""));
    (
        dir.join(format!("{stem}_map.png")),
        dir.join(format!("{stem}_raw.png")),
    )
}

/// Encodes an RGB buffer of the figure size as PNG and writes it atomically.
fn write_png(path: &Path, rgb: &[u8]) -> Result<()> {
    let mut out = Vec::with_capacity(rgb.len() / 8);
    {
        let mut enc = png::Encoder::new(&mut out, WIDTH, HEIGHT);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().map_err(|e| plot_error(path, e))?;
        w.write_image_data(rgb).map_err(|e| plot_error(path, e))?;
    }
    crate::io::atomic::write_bytes_atomic(path, &out)
}

/// evo's `jet`-like colour of `t ∈ [0, 1]`.
fn jet(t: f64) -> RGBColor {
    let t = t.clamp(0.0, 1.0);
    let f = |x: f64| ((1.5 - (4.0 * t - x).abs()).clamp(0.0, 1.0) * 255.0) as u8;
    RGBColor(f(3.0), f(2.0), f(1.0))
}

/// The two world axes along which `p` spreads most, in axis order.
pub fn plane_of_most_motion(p: &[Vector3<f64>]) -> (usize, usize) {
    let mut spread = [0.0f64; 3];
    for (k, s) in spread.iter_mut().enumerate() {
        let (lo, hi) = p
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v[k]), b.max(v[k]))
            });
        *s = if hi >= lo { hi - lo } else { 0.0 };
    }
    // Ties (a flat or empty path) drop the last axis first: z, then y.
    let least = (0..3)
        .rev()
        .min_by(|&a, &b| spread[a].total_cmp(&spread[b]))
        .unwrap_or(2);
    match least {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    }
}

fn range(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = v
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        });
    if lo > hi {
        (0.0, 1.0)
    } else if hi - lo < 1e-12 {
        (lo - 0.5, hi + 0.5)
    } else {
        (lo, hi)
    }
}

/// Draws both figures of a fit (`est` in the SLAM frame, `reference` in the
/// world frame, `fit` the result on them) into `map` and `raw`.
pub fn write_ape_figures(
    est: &Trajectory,
    reference: &Trajectory,
    fit: &TrajectoryAlignment,
    map: &Path,
    raw: &Path,
) -> Result<()> {
    font()?;
    let t = fit.transform();
    let aligned: Vec<Vector3<f64>> = fit
        .pairs
        .iter()
        .map(|&(s, _)| t.transform_point(&est.positions[s]))
        .collect();
    let errors = &fit.errors;
    let times: Vec<f64> = fit.pairs.iter().map(|&(s, _)| est.timestamps[s]).collect();
    let t0 = times.first().copied().unwrap_or(0.0);
    draw_map(reference, &aligned, errors, map)?;
    let rel: Vec<f64> = times.iter().map(|x| x - t0).collect();
    draw_raw(&rel, errors, &fit.ape, raw)
}

fn draw_map(
    reference: &Trajectory,
    aligned: &[Vector3<f64>],
    errors: &[f64],
    path: &Path,
) -> Result<()> {
    let (a, b) = plane_of_most_motion(&reference.positions);
    let names = ["x", "y", "z"];
    let all = || reference.positions.iter().chain(aligned.iter());
    let (xlo, xhi) = range(all().map(|p| p[a]));
    let (ylo, yhi) = range(all().map(|p| p[b]));
    // Equal scale on both axes (evo's `equal` aspect), the plot area 1000×700.
    let (cx, cy) = (0.5 * (xlo + xhi), 0.5 * (ylo + yhi));
    let per_px = ((xhi - xlo) / 960.0).max((yhi - ylo) / 640.0) * 1.06;
    let (hx, hy) = (per_px * 500.0, per_px * 350.0);
    let (elo, ehi) = range(errors.iter().copied());
    let mut buf = vec![0u8; (WIDTH * HEIGHT * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (WIDTH, HEIGHT)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_error(path, e))?;
        let (main, bar) = root.split_horizontally(WIDTH - 150);
        let mut chart = ChartBuilder::on(&main)
            .caption(
                "Reference and aligned estimate, coloured by APE",
                ("sans-serif", 26),
            )
            .margin(16)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d(cx - hx..cx + hx, cy - hy..cy + hy)
            .map_err(|e| plot_error(path, e))?;
        chart
            .configure_mesh()
            .x_desc(format!("{} (m)", names[a]))
            .y_desc(format!("{} (m)", names[b]))
            .label_style(("sans-serif", 17))
            .axis_desc_style(("sans-serif", 20))
            .draw()
            .map_err(|e| plot_error(path, e))?;
        let grey = RGBColor(120, 120, 120);
        chart
            .draw_series(LineSeries::new(
                reference.positions.iter().map(|p| (p[a], p[b])),
                grey.stroke_width(2),
            ))
            .map_err(|e| plot_error(path, e))?
            .label("reference")
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 24, y)], grey.stroke_width(2)));
        let colour = |e: f64| jet((e - elo) / (ehi - elo));
        chart
            .draw_series(aligned.windows(2).zip(errors).map(|(w, &e)| {
                PathElement::new(
                    [(w[0][a], w[0][b]), (w[1][a], w[1][b])],
                    colour(e).stroke_width(3),
                )
            }))
            .map_err(|e| plot_error(path, e))?
            .label("estimate (aligned)")
            .legend(move |(x, y)| {
                PathElement::new([(x, y), (x + 24, y)], jet(0.8).stroke_width(3))
            });
        chart
            .configure_series_labels()
            .label_font(("sans-serif", 17))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperLeft)
            .draw()
            .map_err(|e| plot_error(path, e))?;
        // The colour bar.
        let steps = 200;
        let top = 90i32;
        let height = HEIGHT as i32 - 2 * top;
        for i in 0..steps {
            let y0 = top + height - (i + 1) * height / steps;
            let y1 = top + height - i * height / steps;
            bar.draw(&Rectangle::new(
                [(30, y0), (60, y1)],
                jet(f64::from(i) / f64::from(steps)).filled(),
            ))
            .map_err(|e| plot_error(path, e))?;
        }
        let style = ("sans-serif", 17).into_font();
        for k in 0..=4 {
            let v = elo + (ehi - elo) * f64::from(k) / 4.0;
            let y = top + height - k * height / 4;
            bar.draw(&Text::new(format!("{v:.4}"), (66, y - 8), style.clone()))
                .map_err(|e| plot_error(path, e))?;
        }
        bar.draw(&Text::new(
            "APE (m)",
            (20, top - 40),
            ("sans-serif", 19).into_font(),
        ))
        .map_err(|e| plot_error(path, e))?;
        root.present().map_err(|e| plot_error(path, e))?;
    }
    write_png(path, &buf)
}

fn draw_raw(
    times: &[f64],
    errors: &[f64],
    ape: &crate::align::trajectories::ApeStats,
    path: &Path,
) -> Result<()> {
    let (xlo, xhi) = range(times.iter().copied());
    let ymax = errors
        .iter()
        .copied()
        .fold(0.0f64, f64::max)
        .max(ape.mean + ape.std)
        * 1.08;
    let ymax = if ymax > 0.0 { ymax } else { 1.0 };
    let mut buf = vec![0u8; (WIDTH * HEIGHT * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (WIDTH, HEIGHT)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_error(path, e))?;
        let mut chart = ChartBuilder::on(&root)
            .caption("APE w.r.t. translation part (m)", ("sans-serif", 26))
            .margin(16)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d(xlo..xhi, 0.0..ymax)
            .map_err(|e| plot_error(path, e))?;
        chart
            .configure_mesh()
            .x_desc("t (s)")
            .y_desc("APE (m)")
            .label_style(("sans-serif", 17))
            .axis_desc_style(("sans-serif", 20))
            .draw()
            .map_err(|e| plot_error(path, e))?;
        let band = RGBColor(160, 160, 160);
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [
                    (xlo, (ape.mean - ape.std).max(0.0)),
                    (xhi, ape.mean + ape.std),
                ],
                band.mix(0.35).filled(),
            )))
            .map_err(|e| plot_error(path, e))?
            .label("std")
            .legend(move |(x, y)| {
                Rectangle::new([(x, y - 6), (x + 24, y + 6)], band.mix(0.35).filled())
            });
        chart
            .draw_series(LineSeries::new(
                times.iter().copied().zip(errors.iter().copied()),
                RGBColor(60, 60, 60).stroke_width(2),
            ))
            .map_err(|e| plot_error(path, e))?
            .label("APE (m)")
            .legend(|(x, y)| {
                PathElement::new([(x, y), (x + 24, y)], RGBColor(60, 60, 60).stroke_width(2))
            });
        for (name, v, colour) in [
            ("rmse", ape.rmse, RGBColor(31, 119, 180)),
            ("median", ape.median, RGBColor(44, 160, 44)),
            ("mean", ape.mean, RGBColor(214, 39, 40)),
        ] {
            chart
                .draw_series(LineSeries::new(
                    [(xlo, v), (xhi, v)],
                    colour.stroke_width(2),
                ))
                .map_err(|e| plot_error(path, e))?
                .label(format!("{name} {v:.5}"))
                .legend(move |(x, y)| {
                    PathElement::new([(x, y), (x + 24, y)], colour.stroke_width(2))
                });
        }
        chart
            .configure_series_labels()
            .label_font(("sans-serif", 17))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|e| plot_error(path, e))?;
        root.present().map_err(|e| plot_error(path, e))?;
    }
    write_png(path, &buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figure_names_follow_evo() {
        let (m, r) = figure_paths(Path::new("out/ape.png"));
        assert_eq!(m, Path::new("out/ape_map.png"));
        assert_eq!(r, Path::new("out/ape_raw.png"));
    }

    #[test]
    fn the_plane_drops_the_axis_of_least_spread() {
        let p: Vec<Vector3<f64>> = (0..10)
            .map(|i| Vector3::new(i as f64, 0.01 * i as f64, -2.0 * i as f64))
            .collect();
        assert_eq!(plane_of_most_motion(&p), (0, 2));
        assert_eq!(plane_of_most_motion(&[]), (0, 1));
    }

    #[test]
    fn jet_runs_from_blue_to_red() {
        let lo = jet(0.0);
        let hi = jet(1.0);
        assert!(lo.2 > lo.0 && hi.0 > hi.2, "{lo:?} {hi:?}");
    }
}
