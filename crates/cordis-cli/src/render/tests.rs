use super::*;
use cordis_core::{LinkType, Particle};
use serde_json::Value;

/// A chain of `n` particles hanging from a fixed one: springs, dampers, an angle and an anchor.
fn chain(n: usize) -> Scene {
    let mut s = Scene::new(0.01);
    s.gravity = [0.0, -9.81, 0.0];
    for i in 0..n {
        let p = Particle::new(0.1, [i as f64 * 0.1, 0.0, 0.0]);
        s.add_particle(if i == 0 { p.fixed() } else { p });
    }
    s.add_type(
        LinkType::new("rib", LinkKind::Spring)
            .with("stiffness", 50.0)
            .with("rest_length", 0.1),
    );
    s.add_type(LinkType::new("goo", LinkKind::Damper).with("damping", 0.01));
    s.add_type(
        LinkType::new("bend", LinkKind::Angle)
            .with("stiffness", 0.01)
            .with("rest_cos", -1.0),
    );
    s.add_type(LinkType::new("pin", LinkKind::Anchor).with("stiffness", 10.0));
    s.add_type(LinkType::new("air", LinkKind::Drag).with("damping", 0.001));
    for i in 0..n - 1 {
        s.add_link("rib", &[i, i + 1]);
        s.add_link("goo", &[i, i + 1]);
    }
    s.add_link("bend", &[0, 1, 2]);
    s.add_link("pin", &[n - 1]);
    s.add_link("air", &[1]);
    s
}

/// The JSON embedded in the page, parsed back.
fn embedded(page: &str) -> Value {
    let start_tag = "<script id=\"cordis-data\" type=\"application/json\">";
    let start = page.find(start_tag).expect("data element") + start_tag.len();
    let end = start + page[start..].find("</script>").expect("end of data");
    serde_json::from_str(&page[start..end]).expect("the data is JSON")
}

/// Positions decoded as the viewer does: cumulative integer differences times the step.
fn decode(data: &Value, which: &str) -> (usize, Vec<f64>) {
    let q = &data["quant"];
    let step = q["step"].as_f64().unwrap();
    let origin: Vec<f64> = (0..3).map(|k| q["origin"][k].as_f64().unwrap()).collect();
    let n = data["particles"].as_u64().unwrap() as usize;
    let frames = data[which]["frames"].as_u64().unwrap() as usize;
    let ints = data[which]["data"].as_array().unwrap();
    assert_eq!(ints.len(), frames * n * 3);
    let mut acc = vec![0i64; n * 3];
    let mut out = Vec::with_capacity(ints.len());
    for (k, v) in ints.iter().enumerate() {
        acc[k % (n * 3)] += v.as_i64().expect("integers");
        out.push(origin[k % 3] + acc[k % (n * 3)] as f64 * step);
    }
    (frames, out)
}

#[test]
fn the_page_loads_nothing_from_the_network() {
    let s = chain(6);
    let a = s.simulate(30).unwrap();
    let page = render_html(&s, &a, Some(&a), "chain").unwrap();
    let lower = page.to_ascii_lowercase();
    for needle in [
        "http://",
        "https://",
        "//cdn",
        "@import",
        " src=",
        "@font-face",
    ] {
        assert!(!lower.contains(needle), "the page contains {needle:?}");
    }
    // No CSS `url(…)`: every "url(" is the tail of a script name (the PNG export's
    // `toDataURL(`), which loads nothing.
    for (at, _) in lower.match_indices("url(") {
        let before = lower[..at].chars().next_back().unwrap_or(' ');
        assert!(before.is_ascii_alphabetic(), "a CSS url( at byte {at}");
    }
    // One data element and one script, both closed once: nothing else is loaded or run.
    assert_eq!(lower.matches("<script").count(), 2);
    assert_eq!(lower.matches("</script>").count(), 2);
    assert!(page.contains("default-src 'none'"));
}

#[test]
fn the_data_holds_the_scene_and_the_motions() {
    let s = chain(7);
    let a = s.simulate(40).unwrap();
    let mut s2 = s.clone();
    s2.types[0].params[0] = cordis_core::Param::Known(60.0);
    let b = s2.simulate(25).unwrap();
    let page = render_html(&s, &a, Some(&b), "chain").unwrap();
    let d = embedded(&page);
    assert_eq!(d["particles"], 7);
    assert_eq!(d["frames"], 40, "the longer motion sets the slider");
    assert_eq!(d["dt"], 0.01);
    assert_eq!(d["fixed"], serde_json::json!([0]));
    assert_eq!(d["up"], serde_json::json!([0.0, 1.0, 0.0]));
    assert_eq!(d["gravity"], true);
    let types = d["types"].as_array().unwrap();
    assert_eq!(types.len(), 5);
    assert_eq!(types[0]["count"], 6);
    assert_eq!(types[0]["segments"].as_array().unwrap().len(), 12);
    assert_eq!(types[1]["kind"], "damper");
    assert_eq!(types[2]["segments"], serde_json::json!([0, 1, 1, 2]));
    assert_eq!(types[3]["anchors"], serde_json::json!([6]));
    assert_eq!(types[3]["points"], serde_json::json!([0.6, 0.0, 0.0]));
    assert!(types[4].get("segments").is_none(), "drags are not drawn");

    let tolerance = d["quant"]["step"].as_f64().unwrap();
    for (which, t) in [("a", &a), ("b", &b)] {
        let (frames, pos) = decode(&d, which);
        assert_eq!(frames, t.frames());
        let worst = pos
            .iter()
            .zip(t.as_flat())
            .map(|(p, q)| (p - q).abs())
            .fold(0.0, f64::max);
        assert!(worst <= tolerance, "{which}: decoded {worst} m away");
    }
    // About six significant digits at the scene's scale, not more.
    assert!(tolerance > 1e-8 * a.scale() && tolerance < 1e-5 * a.scale());
}

#[test]
fn a_single_motion_has_no_b() {
    let s = chain(3);
    let a = s.simulate(5).unwrap();
    let d = embedded(&render_html(&s, &a, None, "t").unwrap());
    assert!(d["b"].is_null());
    assert_eq!(d["groups"], Value::Null);
}

#[test]
fn names_cannot_close_the_script_or_inject_markup() {
    let mut s = chain(3);
    let evil = "</script><script>alert(1)</script><!--";
    s.types[0].name = evil.to_string();
    s.particles[1].group = Some("</SCRIPT>&".into());
    let a = s.simulate(3).unwrap();
    let title = "<b>\"t\" & 'u'</script>";
    let page = render_html(&s, &a, None, title).unwrap();
    assert_eq!(page.to_ascii_lowercase().matches("</script>").count(), 2);
    assert!(!page.contains("<!--"));
    assert!(page.contains("<title>&lt;b&gt;&quot;t&quot; &amp; &#39;u&#39;&lt;/script&gt;</title>"));
    let d = embedded(&page);
    assert_eq!(d["types"][0]["name"], evil);
    assert_eq!(d["title"], title);
    assert_eq!(d["groups"]["names"][0], "</SCRIPT>&");
    assert_eq!(d["groups"]["of"], serde_json::json!([-1, 0, -1]));
}

#[test]
fn motions_that_do_not_fit_the_scene_are_refused() {
    let s = chain(4);
    let other = chain(5).simulate(3).unwrap();
    let good = s.simulate(3).unwrap();
    let e = render_html(&s, &other, None, "t").unwrap_err();
    assert!(matches!(e, CordisError::Trajectory { .. }), "{e}");
    assert_eq!(
        e.to_string(),
        "trajectory A: has 5 particles, the scene has 4: it is not a motion of this scene"
    );
    let e = render_html(&s, &good, Some(&other), "t").unwrap_err();
    assert!(
        e.to_string().starts_with("trajectory B (--compare): has 5"),
        "{e}"
    );

    let empty = Trajectory::zeros(0, 4);
    let e = render_html(&s, &empty, None, "t").unwrap_err();
    assert!(e.to_string().contains("empty"), "{e}");

    let mut bad = good.clone();
    let mut frame = vec![cordis_core::Vec3::zeros(); 4];
    frame[2].y = f64::NAN;
    bad.set_frame(1, &frame);
    let e = render_html(&s, &good, Some(&bad), "t").unwrap_err();
    assert_eq!(
        e.to_string(),
        "trajectory B (--compare), frame 1, particle 2: not a finite number: the motion diverged"
    );
}

#[test]
fn a_motionless_scene_still_has_a_grid() {
    let mut s = Scene::new(0.1);
    s.add_particle(Particle::new(1.0, [3.0, -2.0, 0.5]).fixed());
    let a = s.simulate(4).unwrap();
    let d = embedded(&render_html(&s, &a, None, "dot").unwrap());
    let step = d["quant"]["step"].as_f64().unwrap();
    assert!(step > 0.0 && step.is_finite());
    let (_, pos) = decode(&d, "a");
    assert!((pos[0] - 3.0).abs() <= step && (pos[1] + 2.0).abs() <= step);
    assert_eq!(
        d["up"],
        serde_json::json!([0.0, 1.0, 0.0]),
        "weightless: y up"
    );
    assert_eq!(d["gravity"], false);
}

#[test]
fn conditional_scenes_carry_groups_and_range() {
    let mut s = Scene::new(0.01);
    for i in 0..4 {
        let g = if i % 2 == 0 { "water" } else { "oil" };
        s.add_particle(Particle::new(1.0, [i as f64 * 0.1, 0.0, 0.0]).in_group(g));
    }
    let mut t = LinkType::new("touch", LinkKind::Conditional)
        .with("stiffness", 10.0)
        .with("rest_length", 0.1)
        .with("range", 0.15);
    t.groups = vec!["oil".into(), "water".into()];
    s.add_type(t);
    let a = s.simulate(3).unwrap();
    let d = embedded(&render_html(&s, &a, None, "fluid").unwrap());
    assert_eq!(d["groups"]["names"], serde_json::json!(["water", "oil"]));
    assert_eq!(d["groups"]["of"], serde_json::json!([0, 1, 0, 1]));
    assert_eq!(d["types"][0]["groups"], serde_json::json!([1, 0]));
    assert_eq!(d["types"][0]["range"], 0.15);
}

/// A cloth of 51 × 51 particles (5,100 springs) over 200 frames stays well under 20 MB.
#[test]
fn a_large_scene_gives_a_reasonable_file() {
    let side = 51;
    let mut s = Scene::new(0.005);
    s.gravity = [0.0, 0.0, -9.81];
    for r in 0..side {
        for c in 0..side {
            let p = Particle::new(0.01, [c as f64 * 0.02, r as f64 * 0.02, 0.0]);
            s.add_particle(if r == side - 1 && (c == 0 || c == side - 1) {
                p.fixed()
            } else {
                p
            });
        }
    }
    s.add_type(
        LinkType::new("edge", LinkKind::Spring)
            .with("stiffness", 20.0)
            .with("rest_length", 0.02)
            .with("damping", 0.01),
    );
    for r in 0..side {
        for c in 0..side {
            let i = r * side + c;
            if c + 1 < side {
                s.add_link("edge", &[i, i + 1]);
            }
            if r + 1 < side {
                s.add_link("edge", &[i, i + side]);
            }
        }
    }
    assert_eq!(s.links.len(), 5100);
    let a = s.simulate(200).unwrap();
    let page = render_html(&s, &a, None, "cloth").unwrap();
    assert!(page.len() < 20_000_000, "{} bytes", page.len());
    // The differences are small: well under 8 bytes per coordinate on average.
    let per_value = page.len() as f64 / (200.0 * (side * side) as f64 * 3.0);
    assert!(per_value < 8.0, "{per_value} bytes per coordinate");
}

#[test]
fn a_plane_is_sent_with_its_unit_normal_and_its_particles() {
    let mut s = cordis_core::examples::bouncing_ball();
    s.types[0].normal = Some([0.0, 0.0, 4.0]);
    s.types[0].point = Some([0.0, 0.0, -0.25]);
    let a = s.simulate(20).unwrap();
    let d = embedded(&render_html(&s, &a, None, "ball").unwrap());
    let plane = &d["types"][0]["plane"];
    assert_eq!(d["types"][0]["kind"], "plane");
    assert_eq!(plane["normal"], serde_json::json!([0.0, 0.0, 1.0]));
    assert_eq!(plane["point"], serde_json::json!([0.0, 0.0, -0.25]));
    assert_eq!(plane["members"], serde_json::json!([0]));
    assert!(d["types"][0].get("segments").is_none());
}

/// Issue 18: the viewer's panels and legend were "A · trajectory" and "B · compared" whatever
/// the files; `cordis render` now names them by their files (cut past 48 characters).
#[test]
fn the_motions_are_named_by_their_labels_cut_when_long() {
    let s = chain(4);
    let a = s.simulate(5).unwrap();
    let long = "x".repeat(60);
    let d = embedded(&render_html_labelled(&s, &a, Some(&a), "t", ["walk.trc", &long]).unwrap());
    assert_eq!(d["labels"][0], "walk.trc");
    let cut = d["labels"][1].as_str().unwrap();
    assert_eq!((cut.chars().count(), cut.ends_with('…')), (48, true));
    let d = embedded(&render_html(&s, &a, None, "t").unwrap());
    assert_eq!(d["labels"], serde_json::json!(["trajectory", "compared"]));
    // The viewer draws them, in the legend and over the side-by-side panels.
    assert_eq!(super::VIEWER_JS.matches("LABELS[0]").count(), 2);
    assert_eq!(super::VIEWER_JS.matches("LABELS[1]").count(), 2);
}
