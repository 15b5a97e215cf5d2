//! `strider-coordinator report` on a small real experiment (STATIC and GENOME, three
//! repeats each): every section, every picture (inline, and as SVG and PNG files), every
//! table as CSV, and no reference the page cannot resolve.

use strider_coordinator::results::report::SECTIONS;
use strider_tests::{run, run_ok, temp_dir};

const EXPERIMENT: &str = "tests/fixtures/report.toml";

/// Every value of `attr="..."` in the page.
fn attribute_values<'a>(html: &'a str, attr: &str) -> Vec<&'a str> {
    let key = format!("{attr}=\"");
    html.match_indices(&key)
        .map(|(i, _)| {
            let rest = &html[i + key.len()..];
            &rest[..rest.find('"').unwrap()]
        })
        .collect()
}

#[test]
fn the_report_of_a_small_experiment_has_every_section_picture_and_table() {
    let dir = temp_dir("report");
    let db = dir.join("report.db");
    run_ok(
        "strider-coordinator",
        &[
            "run",
            EXPERIMENT,
            "--db",
            db.to_str().unwrap(),
            "--workers",
            "2",
        ],
    );
    let pages = dir.join("report");
    run_ok(
        "strider-coordinator",
        &[
            "report",
            "--db",
            db.to_str().unwrap(),
            "--out",
            pages.to_str().unwrap(),
        ],
    );
    let html = std::fs::read_to_string(pages.join("report.html")).unwrap();

    for section in SECTIONS {
        assert!(
            html.contains(&format!("<h2>{section}</h2>")),
            "no section {section}"
        );
    }
    // Pictures: the four curves, the library map, the pair maps, and drawings.
    let figures = attribute_values(&html, "figure id");
    for name in [
        "qd_score",
        "qd_score_by_evaluations",
        "best_fitness",
        "mean_fitness",
        "lowest_fitness",
        "coverage",
        "library_map",
        "pair_maps",
        "design_1",
    ] {
        assert!(figures.contains(&name), "no picture {name}: {figures:?}");
    }
    // Each inline (self-contained) and also a file of each kind.
    assert_eq!(html.matches("<svg ").count(), figures.len());
    for name in &figures {
        let svg = std::fs::read_to_string(pages.join(format!("{name}.svg"))).unwrap();
        assert!(
            svg.starts_with("<svg ") && svg.trim_end().ends_with("</svg>"),
            "{name}.svg"
        );
        let png = std::fs::read(pages.join(format!("{name}.png"))).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "{name}.png is not a PNG");
    }
    // Nothing to fetch: no src, and every link names a file the report wrote.
    assert!(attribute_values(&html, "src").is_empty());
    let links = attribute_values(&html, "href");
    assert!(links.len() >= 2 * figures.len() + 6, "{links:?}");
    for link in links {
        assert!(pages.join(link).is_file(), "broken link {link}");
    }
    // The tables hold what the designer reads.
    let mw = std::fs::read_to_string(pages.join("mann_whitney.csv")).unwrap();
    assert_eq!(mw.lines().count(), 3, "{mw}");
    assert!(mw.contains("static vs genome,final best fitness"), "{mw}");
    assert!(mw.contains("significant at 0.05"), "{mw}");
    let table5 = std::fs::read_to_string(pages.join("top_designs_features.csv")).unwrap();
    assert!(
        table5.starts_with("scheme,designs,d1 total_leg_length"),
        "{table5}"
    );
    assert_eq!(table5.lines().count(), 3, "{table5}");
    let gens = std::fs::read_to_string(pages.join("per_generation.csv")).unwrap();
    // Per scheme: QD score and coverage for generations 0..=8; the three fitness figures
    // only where some repeat's library holds a design (QD score above 0): an empty
    // library has no fitness.
    let rows: Vec<Vec<&str>> = gens
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    for scheme in ["static", "genome"] {
        let generations = |figure: &str| -> Vec<&str> {
            rows.iter()
                .filter(|r| r[0] == scheme && r[1] == figure)
                .map(|r| r[2])
                .collect()
        };
        assert_eq!(generations("qd_score").len(), 9, "{gens}");
        assert_eq!(generations("coverage").len(), 9, "{gens}");
        let holding: Vec<&str> = rows
            .iter()
            .filter(|r| r[0] == scheme && r[1] == "qd_score" && r[4].parse::<f64>().unwrap() > 0.0)
            .map(|r| r[2])
            .collect();
        if scheme == "static" {
            assert!(!holding.is_empty(), "{gens}");
        }
        for figure in ["best_fitness", "mean_fitness", "lowest_fitness"] {
            assert_eq!(generations(figure), holding, "{scheme} {figure}: {gens}");
        }
    }
    assert!(
        gens.starts_with("scheme,figure,generation,evaluations,mean,sd\n"),
        "{gens}"
    );
    assert!(gens.contains("\nstatic,qd_score,0,"), "{gens}");
    // Numbers in the CSVs are numbers, whole: p-values and rule coefficients parse.
    for line in mw.lines().skip(1) {
        let p: f64 = line.split(',').nth(3).unwrap().parse().unwrap();
        assert!((0.0..=1.0).contains(&p), "{line}");
    }
    let rules = std::fs::read_to_string(pages.join("design_rules.csv")).unwrap();
    assert!(
        rules.starts_with(
            "scheme,designs,kept,target,intercept,coef_total_leg_length,coef_total_mass,"
        ),
        "{rules}"
    );
    for line in rules.lines().skip(1) {
        let fields: Vec<&str> = line.split(',').collect();
        assert_eq!(fields.len(), 13, "{line}");
        for f in fields[4..].iter().filter(|f| !f.is_empty()) {
            f.parse::<f64>()
                .unwrap_or_else(|_| panic!("{f} in {line} is not a number"));
        }
    }
    // Maps: edge bins open, units on the axes, and the colour scale says how it was set.
    let map = std::fs::read_to_string(pages.join("library_map.svg")).unwrap();
    assert!(
        map.contains("&lt; 55 kg") && map.contains("≥ 70 kg"),
        "{map}"
    );
    assert!(map.contains("d2 total_mass (kg, with payload)"), "{map}");
    assert!(map.contains("linear"), "{map}");
    assert!(html.contains("The red ring marks MAX"));
    look_at_it_in_chromium(&pages, &dir);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Debian's Chromium, if installed (`.ci/run` installs it).
fn chromium() -> Option<&'static str> {
    ["chromium", "chromium-browser"]
        .into_iter()
        .find(|c| strider_tests::installed(c))
}

/// Runs headless Chromium on the report with `args`; returns its stdout.
fn headless(
    chromium: &str,
    profile: &std::path::Path,
    page: &std::path::Path,
    args: &[&str],
) -> String {
    // No network, no first-run work: on a closed machine these would only fail and slow
    // the start.
    let out = std::process::Command::new(chromium)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--hide-scrollbars",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .args(args)
        .arg(format!("file://{}", page.display()))
        .output()
        .expect("chromium starts");
    assert!(
        out.status.success(),
        "chromium {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The page as a browser renders it: the DOM Chromium builds holds the key elements
/// (the QD-score curves, legends with units), and a screenshot of the top of the page is
/// a page of pictures, not a blank or an error page.
fn look_at_it_in_chromium(pages: &std::path::Path, dir: &std::path::Path) {
    let Some(chromium) = chromium() else {
        strider_tests::skip_without("Chromium (Debian's chromium package)");
        return;
    };
    let page = pages.join("report.html");
    let dom = headless(chromium, &dir.join("profile-dom"), &page, &["--dump-dom"]);
    for (what, needle) in [
        (
            "the QD-score curve",
            "<figure id=\"qd_score\" class=\"small\">\n<svg",
        ),
        (
            "the QD score against evaluations",
            "<figure id=\"qd_score_by_evaluations\"",
        ),
        ("the QD score's axis", "QD score (sum of fitness)"),
        ("the evaluations axis", "evaluations (candidates)"),
        (
            "the colour legend with its unit",
            "fitness (1 / cost of transport)",
        ),
        (
            "a map axis with its unit",
            "d2 total_mass (kg, with payload)",
        ),
        ("the map's key", "Key: one block of the map, enlarged"),
    ] {
        assert!(
            dom.contains(needle),
            "no {what} ({needle}) in the page Chromium built"
        );
    }

    let shot = dir.join("report.png");
    headless(
        chromium,
        &dir.join("profile-shot"),
        &page,
        &[
            "--window-size=1280,2000",
            &format!("--screenshot={}", shot.display()),
        ],
    );
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&shot).unwrap()));
    let mut reader = decoder.read_info().expect("a PNG");
    let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
    let frame = reader.next_frame(&mut pixels).unwrap();
    assert_eq!((frame.width, frame.height), (1280, 2000));
    let channels = frame.color_type.samples();
    let rgb: Vec<&[u8]> = pixels[..frame.buffer_size()]
        .chunks(channels)
        .map(|p| &p[..3])
        .collect();
    let inked = rgb.iter().filter(|p| p.iter().any(|&c| c < 200)).count();
    let colours: std::collections::HashSet<&[u8]> = rgb.iter().copied().collect();
    // Text, axes and coloured curves: a blank page has one colour, an error page a few.
    assert!(
        inked * 50 > rgb.len(),
        "{inked} of {} pixels inked",
        rgb.len()
    );
    assert!(colours.len() > 200, "{} colours", colours.len());
    // Two curves side by side at the top: ink on both halves of the first rows of pictures.
    let row = |y: usize, x0: usize, x1: usize| {
        (x0..x1).any(|x| rgb[y * 1280 + x].iter().any(|&c| c < 200))
    };
    let (left, right) = (
        (300..700).any(|y| row(y, 0, 640)),
        (300..700).any(|y| row(y, 640, 1280)),
    );
    assert!(left && right, "the first curves are not side by side");
}

#[test]
fn a_report_of_a_missing_run_is_refused_by_name() {
    let dir = temp_dir("report-refusal");
    let out = run(
        "strider-coordinator",
        &[
            "report",
            "--db",
            dir.join("none.db").to_str().unwrap(),
            "--out",
            dir.join("r").to_str().unwrap(),
        ],
    );
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("no database at"));
    std::fs::remove_dir_all(&dir).unwrap();
}
