//! The sweep's plot: RMSE against time, both logarithmic, one panel per
//! area-light model and one line per sampling pattern (and adaptive mode);
//! the `exact` model's single point is drawn in every panel.

use std::path::Path;
use std::sync::OnceLock;

use plotters::prelude::*;
use plotters::style::FontStyle;

use super::sweep::Row;
use super::{CliError, PlotTime};
use crate::render::output::write_rgb8;
use crate::render::{AreaLightModel, Sampling};

const FONT: &str = "sans-serif";

/// Colours by pattern (index in `Sampling::ALL`, cycling for new ones).
const COLOURS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(23, 190, 207),
];

/// plotters' ab_glyph backend draws only registered fonts; egui's bundled
/// Ubuntu-Light (compiled in with the viewer) saves shipping a font file.
fn register_font() -> Result<(), CliError> {
    static DONE: OnceLock<bool> = OnceLock::new();
    let ok = *DONE.get_or_init(|| {
        let mut defs = egui::FontDefinitions::default();
        let Some(data) = defs
            .font_data
            .remove("Ubuntu-Light")
            .or_else(|| defs.font_data.pop_first().map(|(_, d)| d))
        else {
            return false;
        };
        // The bytes are static inside egui; leaking the small handle gives
        // them the 'static lifetime plotters wants, without a copy.
        let data: &'static egui::FontData = Box::leak(Box::new((*data).clone()));
        plotters::style::register_font(FONT, FontStyle::Normal, data.bytes()).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(CliError::other("plot: no usable font"))
    }
}

fn index_of<T: PartialEq>(all: &[T], x: &T) -> usize {
    all.iter().position(|a| a == x).unwrap_or(0)
}

/// Panel size; one panel per area-light model, up to three in a row.
const PANEL: (u32, u32) = (640, 700);
const TITLE_HEIGHT: u32 = 44;

/// Writes the plot of `rows` as a PNG: one panel per area-light model,
/// one line per sampling pattern (dashed with hollow markers: adaptive),
/// on shared axes. `time` picks the x axis (CPU time is divided by
/// `threads`).
pub fn plot(
    path: &Path,
    title: &str,
    rows: &[Row],
    time: PlotTime,
    threads: usize,
) -> Result<(), CliError> {
    register_font()?;
    let fail = |e: &dyn std::fmt::Display| CliError::other(format!("plot: {e}"));
    let x_of = |r: &Row| match time {
        PlotTime::Wall => r.time_s,
        PlotTime::Cpu => r.cpu_s / threads.max(1) as f64,
    };
    // Log axes cannot show a zero error or time.
    let points: Vec<&Row> = rows
        .iter()
        .filter(|r| r.rmse > 0.0 && r.rmse.is_finite() && x_of(r) > 0.0)
        .collect();
    if points.is_empty() {
        return Err(CliError::other(
            "plot: no configuration with a time and an error > 0",
        ));
    }
    let fold = |f: &dyn Fn(&Row) -> f64| {
        points
            .iter()
            .map(|r| f(r))
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            })
    };
    let (t0, t1) = fold(&x_of);
    let (e0, e1) = fold(&|r| r.rmse);
    // The exact model's one point goes into every panel (a black
    // triangle), not a panel of its own.
    let exact = points
        .iter()
        .find(|r| r.model == AreaLightModel::Exact)
        .copied();
    let mut models: Vec<AreaLightModel> = Vec::new();
    for r in &points {
        if !models.contains(&r.model) && (r.model != AreaLightModel::Exact || exact.is_none()) {
            models.push(r.model);
        }
    }
    if models.is_empty() {
        models.push(AreaLightModel::Exact);
    }
    let cols = models.len().clamp(1, 3);
    let grid_rows = models.len().div_ceil(cols);
    let size = (
        PANEL.0 * cols as u32,
        PANEL.1 * grid_rows as u32 + TITLE_HEIGHT,
    );

    let mut buf = vec![0u8; (size.0 * size.1 * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| fail(&e))?;
        let body = root.titled(title, (FONT, 26)).map_err(|e| fail(&e))?;
        let panels = body.split_evenly((grid_rows, cols));
        for (panel, &model) in panels.iter().zip(&models) {
            let mut chart = ChartBuilder::on(panel)
                .caption(format!("model: {}", model.name()), (FONT, 22))
                .margin(14)
                .x_label_area_size(52)
                .y_label_area_size(78)
                .build_cartesian_2d(
                    ((t0 / 1.5)..(t1 * 1.5)).log_scale(),
                    // A decade of room below the lowest error: the legend
                    // sits there, clear of every line.
                    ((e0 / 15.0)..(e1 * 1.5)).log_scale(),
                )
                .map_err(|e| fail(&e))?;
            chart
                .configure_mesh()
                .x_desc(match time {
                    PlotTime::Wall => "wall time per image, s (median)",
                    PlotTime::Cpu => "CPU time per image / threads, s (median)",
                })
                .y_desc("RMSE against the converged reference")
                .x_label_formatter(&|x| format_tick(*x))
                .y_label_formatter(&|y| format!("{y:.0e}"))
                .label_style((FONT, 15))
                .axis_desc_style((FONT, 17))
                .draw()
                .map_err(|e| fail(&e))?;
            let mut series: Vec<(Sampling, bool)> = Vec::new();
            for r in points.iter().filter(|r| r.model == model) {
                if !series.contains(&(r.sampling, r.adaptive)) {
                    series.push((r.sampling, r.adaptive));
                }
            }
            for (sampling, adaptive) in series {
                // Joined in the order swept (growing ray count), so that
                // noisy times show as kinks rather than scrambling the line.
                let line: Vec<(f64, f64)> = points
                    .iter()
                    .filter(|r| {
                        r.model == model && r.sampling == sampling && r.adaptive == adaptive
                    })
                    .map(|r| (x_of(r), r.rmse))
                    .collect();
                let colour = COLOURS[index_of(&Sampling::ALL, &sampling) % COLOURS.len()];
                let style = colour.stroke_width(2);
                let label = if adaptive {
                    format!("{} + adaptive", sampling.name())
                } else {
                    sampling.name().to_string()
                };
                if adaptive {
                    chart
                        .draw_series(DashedLineSeries::new(line.clone(), 7, 5, style))
                        .map_err(|e| fail(&e))?
                        .label(label)
                        .legend(move |(x, y)| {
                            EmptyElement::at((x, y))
                                + PathElement::new(vec![(0, 0), (9, 0)], style)
                                + PathElement::new(vec![(15, 0), (24, 0)], style)
                        });
                } else {
                    chart
                        .draw_series(LineSeries::new(line.clone(), style))
                        .map_err(|e| fail(&e))?
                        .label(label)
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], style));
                }
                chart
                    .draw_series(line.iter().map(|&p| {
                        let marker = if adaptive {
                            colour.stroke_width(2)
                        } else {
                            colour.filled()
                        };
                        Circle::new(p, 4, marker)
                    }))
                    .map_err(|e| fail(&e))?;
            }
            if let Some(r) = exact {
                let p = (x_of(r), r.rmse);
                chart
                    .draw_series(std::iter::once(TriangleMarker::new(p, 9, BLACK.filled())))
                    .map_err(|e| fail(&e))?
                    .label("exact (RMSE vs 4096 stratified rays)")
                    .legend(|(x, y)| TriangleMarker::new((x + 12, y), 7, BLACK.filled()));
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::LowerLeft)
                .label_font((FONT, 15))
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()
                .map_err(|e| fail(&e))?;
        }
        root.present().map_err(|e| fail(&e))?;
    }
    write_rgb8(path, size.0, size.1, &buf).map_err(CliError::other)
}

/// Tick labels of the time axis: only 1, 2 and 5 of each decade are
/// labelled (a log axis ticks every digit, and 0.06–0.09 ran together);
/// the other ticks keep their grid line.
fn format_tick(x: f64) -> String {
    if !(x > 0.0 && x.is_finite()) {
        return String::new();
    }
    let decade = 10f64.powf(x.log10().floor());
    let digit = (x / decade).round();
    if ![1.0, 2.0, 5.0].contains(&digit) || ((x / decade) - digit).abs() > 1e-6 {
        return String::new();
    }
    if x >= 1.0 {
        format!("{x:.0}")
    } else {
        let decimals = (-x.log10()).ceil().max(0.0) as usize;
        format!("{x:.decimals$}")
    }
}

#[cfg(test)]
mod tests {
    use super::format_tick;

    #[test]
    fn the_time_axis_labels_one_two_and_five_of_each_decade() {
        let labels: Vec<String> = [
            0.01, 0.02, 0.03, 0.05, 0.06, 0.09, 0.1, 0.2, 0.4, 0.5, 1.0, 2.0, 3.0,
        ]
        .iter()
        .map(|&x| format_tick(x))
        .collect();
        assert_eq!(
            labels,
            [
                "0.01", "0.02", "", "0.05", "", "", "0.1", "0.2", "", "0.5", "1", "2", ""
            ]
        );
        assert_eq!(format_tick(0.002), "0.002");
        assert_eq!(format_tick(0.0), "");
    }
}
