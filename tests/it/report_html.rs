//! `report.html` and `align --plot` end to end (reduced sizes): the page is in
//! every output set, self-contained, its data block holds what the figures
//! need, its summary numbers are the report's; the APE figures are PNGs of the
//! documented size; bad arguments fail with exit 1, not a panic.

use std::path::Path;

use slam2world::cli::main_with_args;
use slam2world::io::mcap::WorldFlavor;
use slam2world::io::read_mcap;
use slam2world::map::MapParams;
use slam2world::pipeline::{convert, ConvertOptions, Recording, REPORT_HTML, REPORT_JSON};

fn run(args: &[&str]) -> i32 {
    let mut v = vec!["slam2world"];
    v.extend_from_slice(args);
    main_with_args(v)
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The JSON block of a page.
fn data_block(html: &str) -> serde_json::Value {
    let start = html
        .find(r#"<script id="s2w-data" type="application/json">"#)
        .expect("a data block");
    let rest = &html[start..];
    let open = rest.find('>').unwrap() + 1;
    let close = rest.find("</script>").unwrap();
    serde_json::from_str(&rest[open..close]).unwrap()
}

/// `(doc, key, data-value)` of every number on the page taken from a report.
fn numbers(html: &str) -> Vec<(String, String, String)> {
    let mut out = Vec::new();
    for part in html.split("<span class=\"num\" ").skip(1) {
        let attr = |name: &str| {
            let k = format!("{name}=\"");
            part.find(&k).map(|i| {
                let v = &part[i + k.len()..];
                v[..v.find('"').unwrap()].to_string()
            })
        };
        if let (Some(doc), Some(key), Some(value)) =
            (attr("data-doc"), attr("data-key"), attr("data-value"))
        {
            out.push((doc, key, value));
        }
    }
    out
}

fn lookup<'a>(doc: &'a serde_json::Value, key: &str) -> &'a serde_json::Value {
    key.split('.').fold(doc, |d, k| match k.parse::<usize>() {
        Ok(i) if d.is_array() => &d[i],
        _ => &d[k],
    })
}

#[test]
fn a_conversion_writes_a_self_contained_page_with_the_reports_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("s.mcap");
    assert_eq!(run(&["simulate", "-o", s(&log), "--reduced", "8"]), 0);
    let rec = Recording::from(read_mcap(&log, &Default::default()).unwrap());
    let opts = ConvertOptions {
        map: Some(MapParams::new(0.2)),
        ..ConvertOptions::default()
    };
    let conv = convert(&rec, &opts).unwrap();
    let out = dir.path().join("out");
    conv.write_all(&out, WorldFlavor::Foxglove).unwrap();
    let html = std::fs::read_to_string(out.join(REPORT_HTML)).unwrap();
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join(REPORT_JSON)).unwrap()).unwrap();
    assert!(!html.contains("http://") && !html.contains("https://"));
    assert!(html.contains("getContext(\"webgl2\""));
    let data = data_block(&html);
    // The embedded report is report.json (the same write time in both).
    assert_eq!(data["report"], report);
    let f = &data["figures"];
    assert_eq!(
        f["pairs"]["error"].as_array().unwrap().len(),
        conv.report.pairs.len()
    );
    assert_eq!(
        f["scale_factors"].as_array().unwrap().len(),
        conv.report.pairs.len() - 1
    );
    assert_eq!(f["cloud"]["n_total"], conv.cloud.len());
    assert_eq!(
        f["voxels"]["n_total"],
        conv.report.octree.as_ref().unwrap().leaves_occupied
    );
    // Every number shown is the report's, exactly.
    let nums = numbers(&html);
    assert!(nums.len() > 30, "{}", nums.len());
    for (doc, key, value) in &nums {
        assert_eq!(doc, "report");
        let want = lookup(&report, key);
        assert!(
            !want.is_null() || value == "null",
            "{key}: missing in report.json"
        );
        let got: serde_json::Value = serde_json::from_str(value).unwrap();
        assert_eq!(&got, want, "{key}");
    }
}

#[test]
fn align_writes_the_figures_and_the_page() {
    let dir = tempfile::tempdir().unwrap();
    // A reference loop and the same path in another frame, a third of the scale.
    let mut reference = String::new();
    let mut est = String::new();
    for i in 0..200 {
        let t = f64::from(i) * 0.1;
        let (x, y, z) = (
            3.0 * (0.3 * t).cos(),
            2.0 * (0.3 * t).sin(),
            0.1 * (t).sin(),
        );
        reference += &format!("{t} {x} {y} {z} 0 0 0 1\n");
        est += &format!(
            "{t} {} {} {} 0 0 0 1\n",
            y / 3.0 + 1.0,
            -x / 3.0,
            z / 3.0 + 0.001 * (7.0 * t).sin()
        );
    }
    let (e, r) = (dir.path().join("est.txt"), dir.path().join("ref.txt"));
    std::fs::write(&e, est).unwrap();
    std::fs::write(&r, reference).unwrap();
    let save = dir.path().join("ape.png");
    let page = dir.path().join("align.html");
    assert_eq!(
        run(&[
            "align",
            s(&e),
            s(&r),
            "--save-plot",
            s(&save),
            "--html",
            s(&page)
        ]),
        0
    );
    for name in ["ape_map.png", "ape_raw.png"] {
        let bytes = std::fs::read(dir.path().join(name)).unwrap();
        let dec = png::Decoder::new(std::io::Cursor::new(bytes));
        let reader = dec.read_info().unwrap();
        let info = reader.info();
        assert_eq!((info.width, info.height), (1200, 800), "{name}");
    }
    let html = std::fs::read_to_string(&page).unwrap();
    let nums = numbers(&html);
    assert!(nums.iter().any(|(d, k, _)| d == "align" && k == "scale"));
    let data = data_block(&html);
    let scale = data["report"]["scale"].as_f64().unwrap();
    assert!((scale - 3.0).abs() < 0.01, "{scale}");
    assert_eq!(data["figures"]["cloud"], serde_json::Value::Null);
    // A folder that does not exist is an error (exit 1), nothing half-written.
    let bad = dir.path().join("missing").join("ape.png");
    assert_eq!(run(&["align", s(&e), s(&r), "--save-plot", s(&bad)]), 1);
    assert_eq!(
        run(&[
            "align",
            s(&e),
            s(&r),
            "--html",
            s(&dir.path().join("no/x.html"))
        ]),
        1
    );
}
