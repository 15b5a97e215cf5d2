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
    let report_into = |out: &std::path::Path| {
        run(
            "strider-coordinator",
            &[
                "report",
                "--db",
                db.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ],
        )
    };
    let pages = dir.join("report");
    let out = report_into(&pages);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let html = std::fs::read_to_string(pages.join("report.html")).unwrap();

    // All files or none: a directory where report.html goes refuses the whole report,
    // and the designs folder it made is removed again (the output folder was the user's).
    let blocked = dir.join("blocked");
    std::fs::create_dir_all(blocked.join("report.html")).unwrap();
    assert!(!report_into(&blocked).status.success());
    let left: Vec<_> = std::fs::read_dir(&blocked)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left, ["report.html"], "{left:?}");

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
        match link.strip_prefix('#') {
            Some(id) => assert!(html.contains(&format!("id=\"{id}\"")), "no #{id}"),
            None => assert!(pages.join(link).is_file(), "broken link {link}"),
        }
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
    // One meaning of evaluations: the report's are the mean over a scheme's repeats of the
    // exported cumulative_evaluations (candidates drawn and checked, refusals included).
    let exported = String::from_utf8(
        run_ok(
            "strider-coordinator",
            &[
                "export",
                "--db",
                db.to_str().unwrap(),
                "--format",
                "generations-csv",
            ],
        )
        .stdout,
    )
    .unwrap();
    let header: Vec<&str> = exported.lines().next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    for scheme in ["static", "genome"] {
        for g in [0, 8] {
            let counts: Vec<f64> = exported
                .lines()
                .skip(1)
                .map(|l| l.split(',').collect::<Vec<_>>())
                .filter(|f| f[col("scheme")] == scheme && f[col("generation")] == g.to_string())
                .map(|f| f[col("cumulative_evaluations")].parse().unwrap())
                .collect();
            let mean = counts.iter().sum::<f64>() / counts.len() as f64;
            let reported: f64 = rows
                .iter()
                .find(|r| r[0] == scheme && r[1] == "qd_score" && r[2] == g.to_string())
                .map(|r| r[3].parse().unwrap())
                .unwrap();
            assert_eq!(reported, mean, "{scheme} generation {g}: {counts:?}");
        }
    }
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
    // Every word for what a near miss misses is defined on the page.
    for sh in strider_common::Shortfall::ALL {
        assert!(
            html.contains(&format!("<dt>{}</dt><dd>", sh.label())),
            "{} is not defined",
            sh.label()
        );
    }
    look_at_it_in_chromium(&pages, &dir);
    click_through_the_workbench(&pages, &db, &dir);
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

/// The design the database stores in `cell` of `run`'s library: fitness and the trial's
/// speed, cost of transport and mass (with payload), read with sqlite3 as a user would.
fn stored_elite(db: &std::path::Path, run: u64, cell: u64) -> (f64, f64, f64, f64) {
    let text = strider_tests::sqlite(
        db,
        &format!(
            "SELECT c.fitness, k.outcome FROM cells c JOIN candidates k \
             ON k.run_id = c.run_id AND k.number = c.candidate \
             WHERE c.run_id = {run} AND c.cell = {cell}"
        ),
    );
    let (fitness, outcome) = text.trim().split_once('|').expect("one elite row");
    let outcome: serde_json::Value = serde_json::from_str(outcome).unwrap();
    let stats = &outcome["stats"];
    let f = |v: &serde_json::Value| v.as_f64().unwrap();
    // The cells row and the candidate's outcome agree; the outcome's JSON keeps every bit
    // (the sqlite3 shell prints 15 digits).
    let exact = f(&outcome["fitness"]);
    let shown: f64 = fitness.parse().unwrap();
    assert!(
        (shown - exact).abs() <= 1e-12 * exact.abs(),
        "{shown} vs {exact}"
    );
    (
        exact,
        f(&stats["speed"]),
        f(&stats["cost_of_transport"]),
        f(&stats["mass"]),
    )
}

/// The design card now open shows the elite in `cell` of `run` as stored, and its
/// downloads are the files `export --elite RUN:CELL` writes.
fn check_card(
    browser: &strider_tests::webdriver::Browser,
    pages: &std::path::Path,
    db: &std::path::Path,
    dir: &std::path::Path,
    run: u64,
    cell: u64,
) {
    let card = browser.find("#card");
    assert!(browser.displayed(&card), "the card did not open");
    let title = browser.find("#card h3");
    assert_eq!(
        browser.attribute(&title, "data-key").as_deref(),
        Some(format!("f{cell}").as_str())
    );
    assert!(browser.text(&title).contains(&format!("cell {cell}")));
    let field = |name: &str| browser.text(&browser.find(&format!("#card td[data-field={name}]")));
    let (fitness, speed, cot, mass) = stored_elite(db, run, cell);
    assert_eq!(field("fitness"), format!("{fitness:.4}"));
    assert_eq!(field("speed"), format!("{speed:.3}"));
    assert_eq!(field("cot"), format!("{cot:.4}"));
    assert_eq!(field("mass"), format!("{mass:.2}"));
    // The card's motor sizing has a row per joint (three per leg) and the drawings load.
    let legs: usize = field("legs").split(' ').next().unwrap().parse().unwrap();
    assert_eq!(
        browser.find_all("#card table.motors tr").len(),
        1 + 3 * legs
    );
    let drawing = browser.find("#card img");
    let loaded = browser.script(
        "const i = document.querySelector('#card img'); return i.complete && i.naturalWidth > 0;",
    );
    assert_eq!(
        loaded,
        serde_json::Value::Bool(true),
        "{:?}",
        browser.attribute(&drawing, "src")
    );
    // Downloads: the same bytes as the command line's.
    let download = |what: &str| {
        let a = browser.find(&format!("#card a[data-download={what}]"));
        let href = browser.attribute(&a, "href").expect("a download link");
        std::fs::read(pages.join(href)).unwrap()
    };
    let elite = format!("{run}:{cell}");
    let genome = dir.join(format!("export_{cell}.json"));
    let urdf = dir.join(format!("export_{cell}.urdf"));
    let db = db.to_str().unwrap();
    run_ok(
        "strider-coordinator",
        &[
            "export",
            "--db",
            db,
            "--elite",
            &elite,
            "--genome",
            genome.to_str().unwrap(),
        ],
    );
    run_ok(
        "strider-coordinator",
        &[
            "export",
            "--db",
            db,
            "--elite",
            &elite,
            "--urdf",
            urdf.to_str().unwrap(),
        ],
    );
    assert_eq!(
        download("genome"),
        std::fs::read(&genome).unwrap(),
        "genome"
    );
    assert_eq!(download("urdf"), std::fs::read(&urdf).unwrap(), "URDF");
    let pose = dir.join(format!("export_{cell}.start_pose.json"));
    assert_eq!(
        download("pose"),
        std::fs::read(&pose).unwrap(),
        "start pose"
    );
    // The replay command a card gives (the genome file with the experiment the report
    // writes beside it) reproduces the stored trial to the bit.
    let a = browser.find("#card a[data-download=genome]");
    let href = browser.attribute(&a, "href").unwrap();
    let replayed: serde_json::Value = serde_json::from_slice(
        &run_ok(
            "strider-worker",
            &[
                "eval",
                pages.join(&href).to_str().unwrap(),
                "--scheme",
                "genome",
                "--experiment",
                pages.join("designs/experiment.toml").to_str().unwrap(),
                "--json",
            ],
        )
        .stdout,
    )
    .unwrap();
    assert_eq!(replayed["fitness"].as_f64(), Some(fitness), "{replayed}");
}

/// The workbench as a designer uses it, in a real Chromium driven by chromedriver: a click
/// on a cell of the library map, then on a row of the table of designs, opens that
/// design's card (checked against the database and the command line's exports); the
/// table sorts by a clicked header; the near misses toggle swaps the table's designs.
fn click_through_the_workbench(
    pages: &std::path::Path,
    db: &std::path::Path,
    dir: &std::path::Path,
) {
    use strider_tests::webdriver::Browser;
    let Some(chromium) = chromium() else {
        strider_tests::skip_without("Chromium (Debian's chromium package)");
        return;
    };
    let Some(browser) = Browser::start(chromium, &dir.join("profile-workbench")) else {
        strider_tests::skip_without("chromedriver (Debian's chromium-driver package)");
        return;
    };
    let page = format!("file://{}", pages.join("report.html").display());
    browser.goto(&page);
    assert_eq!(
        browser.console_errors(),
        Vec::<String>::new(),
        "the page's script failed"
    );
    let run = browser
        .script("return JSON.parse(document.getElementById('design-data').textContent).run;")
        .as_u64()
        .expect("the page names its run");
    // A cell of the library map.
    let cells = browser.find_all("#library_map rect[data-cell]");
    assert!(!cells.is_empty(), "no design on the library map");
    let target = &cells[cells.len() / 2];
    let cell: u64 = browser
        .attribute(target, "data-cell")
        .unwrap()
        .parse()
        .unwrap();
    browser.click(target);
    check_card(&browser, pages, db, dir, run, cell);
    browser.click(&browser.find("#card .close"));
    assert!(
        !browser.displayed(&browser.find("#card")),
        "the card did not close"
    );

    // The table: sorted by fitness, best first; a click on a header sorts by it.
    let rows = browser.find_all("#designs tbody tr");
    assert_eq!(rows.len(), cells.len(), "a row per design of the map");
    let fitness_column = || -> Vec<f64> {
        let header: Vec<String> = browser
            .find_all("#designs thead th")
            .iter()
            .map(|th| browser.text(th))
            .collect();
        let k = header
            .iter()
            .position(|h| h.starts_with("fitness"))
            .expect("a fitness column");
        browser
            .find_all(&format!("#designs tbody td:nth-child({})", k + 1))
            .iter()
            .map(|td| browser.text(td).parse().unwrap())
            .collect()
    };
    let fitness = fitness_column();
    assert!(fitness.windows(2).all(|w| w[0] >= w[1]), "{fitness:?}");
    browser.click(&browser.find("#designs th[data-sort=fitness]"));
    let ascending = fitness_column();
    assert!(ascending.windows(2).all(|w| w[0] <= w[1]), "{ascending:?}");
    // A row opens its design (another than the map's, where there is another).
    let rows = browser.find_all("#designs tbody tr");
    let keys: Vec<String> = rows
        .iter()
        .map(|r| browser.attribute(r, "data-key").unwrap())
        .collect();
    let k = keys
        .iter()
        .position(|k| *k != format!("f{cell}"))
        .unwrap_or(0);
    let (row, key) = (&rows[k], &keys[k]);
    let cell: u64 = key
        .strip_prefix('f')
        .expect("a feasible design")
        .parse()
        .unwrap();
    browser.click(row);
    check_card(&browser, pages, db, dir, run, cell);
    browser.click(&browser.find("#card .close"));

    // A link to a design opens its card.
    browser.goto(&format!("{page}#design={key}"));
    let title = browser.find("#card h3");
    assert!(
        browser.displayed(&browser.find("#card")),
        "#design={key} opened no card"
    );
    assert_eq!(
        browser.attribute(&title, "data-key").as_deref(),
        Some(key.as_str())
    );
    browser.click(&browser.find("#card .close"));

    // The toggle: the near misses, each with what it misses.
    browser.click(&browser.find("input[name=library][value=infeasible]"));
    let near = browser.find_all("#designs tbody tr");
    let stored: usize = strider_tests::sqlite(
        db,
        &format!("SELECT count(*) FROM infeasible_cells WHERE run_id = {run}"),
    )
    .trim()
    .parse()
    .unwrap();
    assert!(
        stored > 0,
        "the run keeps near misses (feasible-infeasible search)"
    );
    assert_eq!(near.len(), stored, "a row per near miss");
    for r in &near {
        assert!(browser.attribute(r, "data-key").unwrap().starts_with('i'));
    }
    assert_eq!(
        browser.console_errors(),
        Vec::<String>::new(),
        "the page's script failed"
    );
}
