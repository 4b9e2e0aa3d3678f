//! `report.html`: the study in one self-contained page a colleague can open offline (no font or
//! file fetched): the verdict, the least clearance to each object, plots of clearance, force and
//! speed over time, the part's path seen from above and from the side with the swept volume's
//! outline and the closest approach marked, the contact events, and the settings and command that
//! made it, in plain HTML and inline SVG (no script); and, when the caller gives one, a turnable
//! 3D view (the viewer's own page with its data inlined, in an `<iframe srcdoc>`).

use crate::Study;
use glam::DVec3;
use serde_json::Value;
use std::fmt::Write as _;

/// Most points a plotted line keeps (evenly spaced; the extremes of the clearance are kept by the
/// series itself).
const MAX_PLOT_POINTS: usize = 2000;
const PLOT_W: f64 = 760.0;
const PLOT_H: f64 = 180.0;
const VIEW_W: f64 = 760.0;
const VIEW_H: f64 = 320.0;

/// Text made safe for HTML.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The start of a study page titled after the scene `title`, up to and with its heading: the
/// shared style (body, tables) and `style`, the page's own rules.
fn page_head(title: &str, style: &str) -> String {
    let t = escape(title);
    format!(
        "<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>vps study: {t}</title><style>\
         body{{font-family:sans-serif;max-width:800px;margin:1em auto;color:#222}}\
         table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:2px 6px;\
         text-align:left;font-size:.9em}}{style}</style></head><body><h1>Assembly study: {t}</h1>"
    )
}

/// `(t, y)` points as an SVG plot with axes labels, `id` for tests; non-finite points are
/// skipped.
fn plot(id: &str, title: &str, unit: &str, points: &[(f64, f64)], colour: &str) -> String {
    let points: Vec<(f64, f64)> = points
        .iter()
        .copied()
        .filter(|(t, y)| t.is_finite() && y.is_finite())
        .collect();
    let stride = points.len().div_ceil(MAX_PLOT_POINTS).max(1);
    let kept: Vec<(f64, f64)> = points.iter().copied().step_by(stride).collect();
    let (t0, t1) = kept
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.0), b.max(p.0))
        });
    let (y0, y1) = kept.iter().fold((0.0f64, f64::NEG_INFINITY), |(a, b), p| {
        (a.min(p.1), b.max(p.1))
    });
    let (left, bottom) = (60.0, 24.0);
    let span_t = if t1 > t0 { t1 - t0 } else { 1.0 };
    let span_y = if y1 > y0 { y1 - y0 } else { 1.0 };
    let x = |t: f64| left + (t - t0) / span_t * (PLOT_W - left - 10.0);
    let y = |v: f64| (PLOT_H - bottom) - (v - y0) / span_y * (PLOT_H - bottom - 10.0);
    let mut line = String::new();
    for (t, v) in &kept {
        let _ = write!(line, "{:.1},{:.1} ", x(*t), y(*v));
    }
    format!(
        "<figure><figcaption>{title}</figcaption><svg id=\"{id}\" width=\"{PLOT_W}\" \
         height=\"{PLOT_H}\" viewBox=\"0 0 {PLOT_W} {PLOT_H}\">\
         <rect x=\"{left}\" y=\"10\" width=\"{w}\" height=\"{h}\" fill=\"#fafafa\" stroke=\"#ccc\"/>\
         <polyline fill=\"none\" stroke=\"{colour}\" stroke-width=\"1.2\" points=\"{line}\"/>\
         <text x=\"4\" y=\"16\" font-size=\"11\">{y1:.3} {unit}</text>\
         <text x=\"4\" y=\"{yb}\" font-size=\"11\">{y0:.3} {unit}</text>\
         <text x=\"{left}\" y=\"{tb}\" font-size=\"11\">{t0:.2} s</text>\
         <text x=\"{tr}\" y=\"{tb}\" font-size=\"11\" text-anchor=\"end\">{t1:.2} s</text>\
         </svg></figure>",
        w = PLOT_W - left - 10.0,
        h = PLOT_H - bottom - 10.0,
        yb = PLOT_H - bottom,
        tb = PLOT_H - 6.0,
        tr = PLOT_W - 10.0,
        y1 = if y1.is_finite() { y1 } else { 0.0 },
        t0 = if t0.is_finite() { t0 } else { 0.0 },
        t1 = if t1.is_finite() { t1 } else { 0.0 },
    )
}

/// The path projected on two world axes (`a`, `b`: 0 = x, 1 = y, 2 = z), with the swept volume's
/// outline, the hand's path, the start and end, and the closest approach.
fn view(id: &str, title: &str, study: &Study, a: usize, b: usize) -> String {
    let names = ["x", "y", "z"];
    let grip: Vec<DVec3> = study.path.iter().map(|f| f.part_position_m).collect();
    let hand: Vec<DVec3> = study.path.iter().map(|f| f.handle_position_m).collect();
    let closest = study.verdict.minimum_clearance.map(|(_, m)| m.closest);
    let swept = study.swept.as_ref().and_then(|s| s.as_ref().ok());
    // The swept region's shadow on the view's plane: cells covered, and the runs of each row.
    let mut runs: Vec<(DVec3, usize)> = Vec::new();
    let mut cell = 0.0;
    if let Some(s) = swept {
        let dims = s.spec.dims.map(|d| d as usize);
        let (na, nb) = (dims[a], dims[b]);
        let mut covered = vec![false; na * nb];
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    if s.inside[i + dims[0] * (j + dims[1] * k)] {
                        let ijk = [i, j, k];
                        covered[ijk[a] + na * ijk[b]] = true;
                    }
                }
            }
        }
        cell = s.spec.voxel_size;
        for v in 0..nb {
            let mut u = 0;
            while u < na {
                if !covered[u + na * v] {
                    u += 1;
                    continue;
                }
                let start = u;
                while u < na && covered[u + na * v] {
                    u += 1;
                }
                let mut corner = s.spec.origin;
                corner[a] += start as f64 * cell;
                corner[b] += v as f64 * cell;
                runs.push((corner, u - start));
            }
        }
    }
    // Bounds of everything drawn.
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    let mut grow = |p: DVec3| {
        for (k, axis) in [a, b].iter().enumerate() {
            lo[k] = lo[k].min(p[*axis]);
            hi[k] = hi[k].max(p[*axis]);
        }
    };
    grip.iter().chain(&hand).for_each(|&p| grow(p));
    if let Some(c) = closest {
        grow(c.on_part_m);
        grow(c.on_object_m);
    }
    for (corner, n) in &runs {
        grow(*corner);
        let mut far = *corner;
        far[a] += *n as f64 * cell;
        far[b] += cell;
        grow(far);
    }
    let (span_a, span_b) = ((hi[0] - lo[0]).max(1e-6), (hi[1] - lo[1]).max(1e-6));
    let scale = ((VIEW_W - 20.0) / span_a).min((VIEW_H - 20.0) / span_b);
    // Centred in the view.
    let (off_a, off_b) = (
        (VIEW_W - span_a * scale) * 0.5,
        (VIEW_H - span_b * scale) * 0.5,
    );
    let px = |p: DVec3| {
        (
            off_a + (p[a] - lo[0]) * scale,
            VIEW_H - off_b - (p[b] - lo[1]) * scale,
        )
    };
    let mut svg = String::new();
    let _ = write!(
        svg,
        "<figure><figcaption>{title} ({} right, {} up; 1 px = {:.2} mm)</figcaption>\
         <svg id=\"{id}\" width=\"{VIEW_W}\" height=\"{VIEW_H}\" viewBox=\"0 0 {VIEW_W} {VIEW_H}\">\
         <rect width=\"{VIEW_W}\" height=\"{VIEW_H}\" fill=\"#fafafa\" stroke=\"#ccc\"/>",
        names[a],
        names[b],
        1e3 / scale
    );
    let _ = write!(svg, "<g fill=\"#c9d7ea\" shape-rendering=\"crispEdges\">");
    for (corner, n) in &runs {
        let mut top = *corner;
        top[b] += cell;
        let (x, y) = px(top);
        let _ = write!(
            svg,
            "<rect x=\"{x:.1}\" y=\"{y:.1}\" width=\"{:.1}\" height=\"{:.1}\"/>",
            *n as f64 * cell * scale,
            cell * scale
        );
    }
    let _ = write!(svg, "</g>");
    let line = |points: &[DVec3]| {
        let stride = points.len().div_ceil(MAX_PLOT_POINTS).max(1);
        let mut text = String::new();
        for p in points.iter().step_by(stride).chain(points.last()) {
            let (x, y) = px(*p);
            let _ = write!(text, "{x:.1},{y:.1} ");
        }
        text
    };
    let _ = write!(
        svg,
        "<polyline fill=\"none\" stroke=\"#999\" stroke-dasharray=\"4 3\" points=\"{}\"/>\
         <polyline fill=\"none\" stroke=\"#1f5fbf\" stroke-width=\"1.5\" points=\"{}\"/>",
        line(&hand),
        line(&grip)
    );
    if let (Some(first), Some(last)) = (grip.first(), grip.last()) {
        let (x0, y0) = px(*first);
        let (x1, y1) = px(*last);
        let _ = write!(
            svg,
            "<circle cx=\"{x0:.1}\" cy=\"{y0:.1}\" r=\"4\" fill=\"#2a2\"/>\
             <rect x=\"{:.1}\" y=\"{:.1}\" width=\"8\" height=\"8\" fill=\"#222\"/>",
            x1 - 4.0,
            y1 - 4.0
        );
    }
    if let Some(c) = closest {
        let (xp, yp) = px(c.on_part_m);
        let (xo, yo) = px(c.on_object_m);
        let _ = write!(
            svg,
            "<line x1=\"{xp:.1}\" y1=\"{yp:.1}\" x2=\"{xo:.1}\" y2=\"{yo:.1}\" stroke=\"#d22\" \
             stroke-width=\"2\"/><circle cx=\"{xp:.1}\" cy=\"{yp:.1}\" r=\"5\" fill=\"none\" \
             stroke=\"#d22\" stroke-width=\"2\"/>"
        );
    }
    svg.push_str("</svg></figure>");
    svg
}

/// The whole page for `study`, made with `settings` (study.json's `settings`). `view_page`, when
/// given, is a complete HTML document (the viewer's standalone page, which this crate does not
/// make) shown in an `<iframe srcdoc>` as the turnable 3D view; the rest of the page needs no
/// script.
pub fn report_html(study: &Study, settings: &Value, view_page: Option<&str>) -> String {
    let v = &study.verdict;
    let names = &study.object_names;
    let name = |o: usize| escape(names.get(o).map_or("?", String::as_str));
    let title = settings["scene_name"].as_str().unwrap_or("scene");
    let mut html = page_head(
        title,
        "#verdict{font-size:1.15em;padding:.6em;background:#eef4ee;border-left:4px solid #2a2}\
         figure{margin:1em 0}figcaption{font-size:.9em;color:#555}",
    );
    let _ = write!(html, "<p id=\"verdict\">{}</p>", escape(&v.line));
    if let Some(n) = settings["cluster_stale_shares"].as_u64().filter(|&n| n > 0) {
        let _ = write!(
            html,
            "<p id=\"caution\">Caution: the session's cluster stood in for {n} late shares with \
             an earlier frame's sums (<code>--max-stale-frames</code>); this study computed every \
             share exactly, so its path can differ from the session's.</p>"
        );
    }
    html.push_str("<h2>Least clearance to each object</h2><table><tr><th>object</th><th>least clearance</th><th>at</th><th>nearest point of the object (m)</th></tr>");
    for (o, c) in study.clearance.objects.iter().enumerate() {
        if let Some(m) = c.minimum {
            let p = m.closest.on_object_m;
            let _ = write!(
                html,
                "<tr><td>{}</td><td>{:.3} mm</td><td>{:.3} s</td><td>{:.4}, {:.4}, {:.4}</td></tr>",
                name(o),
                m.closest.distance_m * 1e3,
                m.time_s,
                p.x,
                p.y,
                p.z
            );
        }
    }
    html.push_str("</table><h2>Over time</h2>");
    let series: Vec<(f64, f64)> = study
        .clearance
        .series_frames
        .iter()
        .enumerate()
        .filter_map(|(k, &i)| Some((study.path[i].time_s, study.clearance.least_at(k)? * 1e3)))
        .collect();
    html.push_str(&plot(
        "plot-clearance",
        "Exact clearance to the nearest object (every 10 ms)",
        "mm",
        &series,
        "#1f5fbf",
    ));
    let force: Vec<(f64, f64)> = study
        .path
        .iter()
        .map(|f| (f.time_s, f.device_force_n.length()))
        .collect();
    html.push_str(&plot(
        "plot-force",
        "Force sent to the device",
        "N",
        &force,
        "#c0392b",
    ));
    let speed: Vec<(f64, f64)> = (1..study.path.len())
        .filter_map(|i| {
            Some((
                study.path[i].time_s,
                crate::path::grip_speed(&study.path, i)? * 1e3,
            ))
        })
        .collect();
    html.push_str(&plot(
        "plot-speed",
        "The part's speed (grip)",
        "mm/s",
        &speed,
        "#27ae60",
    ));
    html.push_str(
        "<h2>The path</h2><p>Blue: the part's grip; dashed grey: the hand; shaded: the swept \
         volume's shadow; green dot: start; black square: end; red: the closest approach (the \
         part's point circled, the line to the object's nearest point).</p>",
    );
    html.push_str(&view("view-top", "From above", study, 0, 1));
    html.push_str(&view("view-side", "From the side", study, 0, 2));
    if let Some(page) = view_page {
        let _ = write!(
            html,
            "<h2>In 3D</h2><p>The scene's meshes, the part at a frame of its path (green line), \
             the hand's path (blue), the closest approach (red) and the swept volume \
             (translucent). Drag to turn, wheel to zoom; the slider moves the part along its \
             path, from the closest approach at first. The view needs JavaScript; everything it \
             shows is in this file.</p><iframe id=\"view-3d\" title=\"the study in 3D\" \
             width=\"100%\" height=\"520\" style=\"border:1px solid #ccc\" \
             srcdoc=\"{}\"></iframe>",
            escape(page)
        );
    }
    html.push_str("<h2>Contact events</h2>");
    if study.contacts.is_empty() {
        html.push_str("<p>None: the scene never pushed on the part.</p>");
    } else {
        html.push_str("<table><tr><th>from</th><th>to</th><th>object</th><th>peak force</th><th>where on the part (m, its frame)</th></tr>");
        for c in &study.contacts {
            let object = c.object.map_or("?".to_string(), name);
            let at = c.on_part_local_m.map_or(String::new(), |p| {
                format!("{:.4}, {:.4}, {:.4}", p.x, p.y, p.z)
            });
            let _ = write!(
                html,
                "<tr><td>{:.3} s</td><td>{:.3} s</td><td>{object}</td><td>{:.2} N</td><td>{at}</td></tr>",
                c.start_s, c.end_s, c.peak_force_n
            );
        }
        html.push_str("</table>");
    }
    if let Some(Ok(s)) = &study.swept {
        let _ = write!(
            html,
            "<h2>Swept volume</h2><p>{:.1} cm³ ({} voxels of {} mm); its surface is \
             <code>swept.stl</code> beside this page.</p>",
            s.volume_m3 * 1e6,
            s.voxels,
            s.spec.voxel_size * 1e3
        );
    }
    let settings_text = serde_json::to_string_pretty(settings).unwrap_or_default();
    let _ = writeln!(
        html,
        "<h2>Settings</h2><pre id=\"settings\">{}</pre><p>Made by vps; every figure is in \
         <code>study.json</code> beside this page.</p></body></html>",
        escape(&settings_text)
    );
    html
}

/// One part of a session of several, as the index page lists it.
pub struct PartEntry<'a> {
    /// The part's name.
    pub name: &'a str,
    /// Its folder, relative to the index page.
    pub folder: &'a str,
    /// Its verdict line.
    pub verdict: &'a str,
}

/// The `report.html` of a study of several moving parts, beside the parts' folders: the scene's
/// name, each part's verdict with a link to its own `report.html`, and the least exact clearance
/// between each pair of parts (`names` every part, the first first). Plain HTML, no script, nothing
/// fetched.
pub fn parts_index_html(
    scene: &str,
    parts: &[PartEntry<'_>],
    names: &[String],
    pairs: &[crate::pairs::PairClearance],
) -> String {
    let mut html = page_head(scene, "");
    let _ = write!(
        html,
        "<p>{n} moving parts, each studied against the static objects in its own folder; the \
         clearance between the parts below.</p>\
         <h2>Parts</h2><table id=\"parts\"><tr><th>part</th><th>verdict</th></tr>",
        n = parts.len()
    );
    for p in parts {
        let _ = write!(
            html,
            "<tr><td><a href=\"{f}/report.html\">{name}</a></td><td>{v}</td></tr>",
            f = escape(p.folder),
            name = escape(p.name),
            v = escape(p.verdict)
        );
    }
    html.push_str(
        "</table><h2>Clearance between the parts</h2><table id=\"pairs\"><tr><th>parts</th>\
         <th>least exact clearance</th><th>at</th></tr>",
    );
    let name = |k: usize| escape(names.get(k).map_or("?", String::as_str));
    for p in pairs {
        let (least, at) = match &p.minimum {
            Some(m) if m.closest.distance_m == 0.0 => (
                "touched or crossed".to_string(),
                format!("{:.3} s", m.time_s),
            ),
            Some(m) => (
                format!("{:.3} mm", m.closest.distance_m * 1e3),
                format!("{:.3} s (frame {})", m.time_s, m.frame),
            ),
            None => (
                "not measured (a mesh without triangles)".into(),
                String::new(),
            ),
        };
        let _ = write!(
            html,
            "<tr><td>{} – {}</td><td>{least}</td><td>{at}</td></tr>",
            name(p.a),
            name(p.b)
        );
    }
    html.push_str(
        "</table><h2>Contact between the parts</h2><table id=\"pair-contacts\"><tr><th>parts</th>\
         <th>from</th><th>to</th><th>peak force on the first</th><th>exact gap at the peak</th></tr>",
    );
    let mut any = false;
    for p in pairs {
        for e in &p.contacts {
            any = true;
            let _ = write!(
                html,
                "<tr><td>{} – {}</td><td>{:.3} s</td><td>{:.3} s</td><td>{:.2} N at {:.3} s</td>\
                 <td>{:.3} mm</td></tr>",
                name(p.a),
                name(p.b),
                e.start_s,
                e.end_s,
                e.peak_force_on_a_n,
                e.peak_s,
                e.distance_at_peak_m * 1e3
            );
        }
    }
    if !any {
        html.push_str("<tr><td colspan=\"5\">no contact between the parts</td></tr>");
    }
    html.push_str(
        "</table><p>Every series: <code>pair_clearance.csv</code>; the figures: \
         <code>pairs.json</code>.</p></body></html>\n",
    );
    html
}
