//! Issue 18 (Deliver 2): docs/file-formats.md documents every link kind's keys, units and
//! defaults, and gives a complete scene per kind. The table is checked against the parser's
//! own lists (`LinkKind::param_specs`, `arity`, `extra_keys`), and every example is loaded,
//! validated and simulated, so the page cannot drift from the code.

use std::collections::{BTreeMap, BTreeSet};

use cordis_core::{LinkKind, Scene};

fn page() -> String {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/file-formats.md");
    std::fs::read_to_string(path).expect("docs/file-formats.md")
}

/// The backticked names in a table cell, in order.
fn ticked(cell: &str) -> Vec<String> {
    cell.split('`')
        .skip(1)
        .step_by(2)
        .map(str::to_string)
        .collect()
}

/// One documented parameter: name, unit, default.
#[derive(Debug, PartialEq)]
struct Documented {
    name: String,
    unit: String,
    default: Option<f64>,
}

fn parameters(cell: &str) -> Vec<Documented> {
    cell.split(", `")
        .map(|item| {
            let item = item.trim().trim_start_matches('`');
            let (name, rest) = item.split_once("` (").unwrap_or_else(|| panic!("{item}"));
            let (unit, rest) = rest.split_once(')').unwrap_or_else(|| panic!("{item}"));
            let default = rest.trim().strip_prefix("= ").map(|d| {
                d.parse::<f64>()
                    .unwrap_or_else(|_| panic!("default of {item}"))
            });
            Documented {
                name: name.to_string(),
                unit: unit.to_string(),
                default,
            }
        })
        .collect()
}

/// The kinds table: kind → (arity, parameters, other keys).
fn kinds_table(page: &str) -> BTreeMap<String, (usize, Vec<Documented>, Vec<String>)> {
    let start = page
        .find("| kind | particles | parameters | other keys |")
        .expect("the kinds table");
    page[start..]
        .lines()
        .skip(2)
        .take_while(|l| l.starts_with('|'))
        .map(|row| {
            let cells: Vec<&str> = row.trim_matches('|').split(" | ").map(str::trim).collect();
            assert_eq!(cells.len(), 4, "{row}");
            let kind = ticked(cells[0]).remove(0);
            (
                kind,
                (
                    cells[1]
                        .parse()
                        .unwrap_or_else(|_| panic!("arity in {row}")),
                    parameters(cells[2]),
                    ticked(cells[3]),
                ),
            )
        })
        .collect()
}

#[test]
fn the_kinds_table_lists_the_parsers_parameters_defaults_and_keys() {
    let table = kinds_table(&page());
    let names: BTreeSet<&str> = LinkKind::ALL.iter().map(|k| k.name()).collect();
    let documented: BTreeSet<&str> = table.keys().map(String::as_str).collect();
    assert_eq!(documented, names, "one row per kind, no other");
    for kind in LinkKind::ALL {
        let (arity, params, extra) = &table[kind.name()];
        assert_eq!(*arity, kind.arity(), "{kind}: particles");
        let want: Vec<(&str, Option<f64>)> = kind.param_specs().to_vec();
        let got: Vec<(&str, Option<f64>)> = params
            .iter()
            .map(|p| (p.name.as_str(), p.default))
            .collect();
        assert_eq!(
            got, want,
            "{kind}: parameters in order, with their defaults"
        );
        assert!(
            params.iter().all(|p| !p.unit.is_empty()),
            "{kind}: a unit each"
        );
        assert_eq!(extra, &kind.extra_keys().to_vec(), "{kind}: other keys");
    }
}

#[test]
fn every_kind_has_a_documented_example_that_loads_and_runs() {
    let page = page();
    let mut covered = BTreeSet::new();
    let mut count = 0;
    for (at, _) in page.match_indices("<!-- example: ") {
        let rest = &page[at + "<!-- example: ".len()..];
        let (claimed, rest) = rest.split_once(" -->").unwrap();
        let body = rest
            .trim_start()
            .strip_prefix("```json\n")
            .expect("a json block");
        let json = &body[..body.find("```").unwrap()];
        let scene = Scene::from_json_str(json)
            .unwrap_or_else(|e| panic!("example `{claimed}` does not load: {e}\n{json}"));
        scene.validate().unwrap();
        let kinds: BTreeSet<&str> = scene.types.iter().map(|t| t.kind.name()).collect();
        for kind in claimed.split(", ") {
            assert!(
                kinds.contains(kind),
                "example `{claimed}` has no {kind} type"
            );
            covered.insert(kind.to_string());
        }
        let traj = scene.simulate(50).unwrap();
        assert!(traj.as_flat().iter().all(|v| v.is_finite()));
        let n = scene.num_particles();
        let moved = (0..n).any(|i| traj.pos(49, i) != traj.pos(0, i));
        assert!(moved, "`{claimed}`: something moves");
        count += 1;
    }
    assert!(count >= 11, "{count} examples");
    let all: BTreeSet<String> = LinkKind::ALL.iter().map(|k| k.name().to_string()).collect();
    assert_eq!(covered, all, "an example per kind");
}

#[test]
fn a_required_parameter_left_out_is_refused_and_a_default_is_applied() {
    // The table's "required" and "= default" are the parser's: spot-check both directions.
    let table = kinds_table(&page());
    for kind in LinkKind::ALL {
        let (_, params, _) = &table[kind.name()];
        for left_out in params {
            let mut ty = serde_json::Map::new();
            ty.insert("kind".into(), kind.name().into());
            for p in params.iter().filter(|p| p.name != left_out.name) {
                ty.insert(p.name.clone(), 0.5.into());
            }
            if kind == LinkKind::Conditional {
                ty.insert("groups".into(), serde_json::json!(["g"]));
            }
            if kind == LinkKind::Tgr {
                ty.insert("signal".into(), "s".into());
            }
            if kind == LinkKind::Plane {
                ty.insert("point".into(), serde_json::json!([0, 0, 0]));
                ty.insert("normal".into(), serde_json::json!([0, 0, 1]));
            }
            let text = serde_json::json!({
                "dt": 0.01,
                "particles": [{"mass": 1.0, "pos": [0, 0, 0], "group": "g"}],
                "signals": {"s": {"shape": "sine", "amplitude": 1.0, "period": 1.0}},
                "types": {"t": ty},
            })
            .to_string();
            let parsed = Scene::from_json_str(&text);
            match left_out.default {
                None => {
                    let e = parsed.expect_err(&text).to_string();
                    assert!(e.contains(&format!("need `{}`", left_out.name)), "{e}");
                }
                Some(d) => {
                    let scene = parsed.unwrap_or_else(|e| panic!("{text}: {e}"));
                    assert_eq!(scene.types[0].value(&left_out.name), Some(d), "{text}");
                }
            }
        }
    }
}
