//! Malformed scenes (SPEC §5.1): each gives one error of the right variant whose place names
//! where to look, and a one-line message that says what is wrong. Never a panic.

use cordis_core::{CordisError, Scene};
use serde_json::{json, Value};

/// A valid scene that each test breaks in one place.
fn base() -> Value {
    json!({
        "format": "cordis-scene/1",
        "dt": 0.01,
        "gravity": [0, 0, -9.81],
        "particles": [
            {"mass": 1.0, "pos": [0, 0, 0], "fixed": true},
            {"mass": 2.0, "pos": [1, 0, 0], "vel": [0, 1, 0], "group": "gas"},
            {"mass": 1.5, "pos": [1, 1, 0], "group": "gas"}
        ],
        "types": {
            "rib": {"kind": "spring", "stiffness": 20.0, "rest_length": 1.0, "damping": 0.1},
            "bend": {"kind": "angle", "stiffness": 2.0, "rest_cos": 0.0},
            "near": {"kind": "conditional", "stiffness": 5.0, "rest_length": 0.5,
                     "range": 0.8, "groups": ["gas"]}
        },
        "links": [
            {"type": "rib", "particles": [0, 1]},
            {"type": "rib", "particles": [1, 2]},
            {"type": "bend", "particles": [0, 1, 2]}
        ]
    })
}

/// `base()` with the value at JSON pointer `at` replaced (or inserted into its object).
fn with(at: &str, v: Value) -> Value {
    let mut root = base();
    let (parent, key) = at.rsplit_once('/').unwrap();
    let target = root.pointer_mut(parent).unwrap();
    match target {
        Value::Object(o) => {
            o.insert(key.to_string(), v);
        }
        Value::Array(a) => a[key.parse::<usize>().unwrap()] = v,
        _ => panic!("bad pointer {at}"),
    }
    root
}

/// `base()` with the key at `at` removed.
fn without(at: &str) -> Value {
    let mut root = base();
    let (parent, key) = at.rsplit_once('/').unwrap();
    root.pointer_mut(parent)
        .unwrap()
        .as_object_mut()
        .unwrap()
        .remove(key)
        .unwrap();
    root
}

fn read(v: &Value) -> Result<Scene, CordisError> {
    Scene::from_json_str(&serde_json::to_string_pretty(v).unwrap())
}

/// Asserts a `Scene` error at `place` whose message contains `says`.
fn scene_error(v: &Value, place: &str, says: &str) {
    check(read(v), place, says, true);
}

fn check(r: Result<Scene, CordisError>, want_place: &str, says: &str, scene_variant: bool) {
    let e = r.expect_err("the scene should be rejected");
    let text = e.to_string();
    assert!(!text.contains('\n'), "not one line: {text}");
    let (place, message) = match &e {
        CordisError::Scene { place, message } if scene_variant => (place, message),
        CordisError::Format { place, message } if !scene_variant => (place, message),
        other => panic!("wrong variant: {other:?}"),
    };
    assert_eq!(place, want_place, "{text}");
    assert!(message.contains(says), "`{text}` does not say `{says}`");
    assert!(text.starts_with(&format!("{want_place}: ")), "{text}");
}

#[test]
fn the_base_scene_is_valid() {
    let s = read(&base()).unwrap();
    assert_eq!((s.particles.len(), s.types.len(), s.links.len()), (3, 3, 3));
}

#[test]
fn bad_json_names_line_and_column() {
    let text = "{\n  \"dt\": 0.01,\n  \"particles\": [}\n}";
    check(
        Scene::from_json_str(text),
        "scene:3:17",
        "invalid JSON",
        false,
    );
}

#[test]
fn bad_json_in_a_file_names_the_file_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.json");
    std::fs::write(&path, "{\"dt\": 0.01,\n \"particles\": [1 2]}").unwrap();
    let place = format!("{}:2:18", path.display());
    check(Scene::from_json_path(&path), &place, "invalid JSON", false);
}

#[test]
fn a_missing_file_is_an_io_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nowhere.json");
    let e = Scene::from_json_path(&path).unwrap_err();
    assert!(
        matches!(&e, CordisError::Io { path: p, .. } if *p == path),
        "{e:?}"
    );
    assert!(e.to_string().starts_with(&path.display().to_string()));
}

#[test]
fn empty_text() {
    check(Scene::from_json_str(""), "scene", "empty", false);
    check(Scene::from_json_str(" \n\t "), "scene", "empty", false);
}

#[test]
fn not_an_object() {
    scene_error(&json!([1, 2]), "scene", "expected an object, got an array");
}

#[test]
fn unknown_kind() {
    scene_error(
        &with("/types/rib/kind", json!("sprung")),
        "types.rib.kind",
        "unknown kind `sprung` (expected one of: spring, damper",
    );
}

#[test]
fn unknown_key_at_top_level() {
    scene_error(
        &with("/gravitee", json!(1)),
        "gravitee",
        "unknown key `gravitee`",
    );
}

#[test]
fn unknown_key_in_a_particle() {
    scene_error(
        &with("/particles/1/velocity", json!([0, 0, 0])),
        "particles[1].velocity",
        "unknown key `velocity` (expected one of: mass, pos, vel, fixed, group, world)",
    );
}

#[test]
fn unknown_key_in_a_type() {
    // `range` is a conditional's parameter, not a spring's.
    scene_error(
        &with("/types/rib/range", json!(1.0)),
        "types.rib.range",
        "unknown key `range`",
    );
}

#[test]
fn unknown_key_in_a_link() {
    scene_error(
        &with("/links/2/weight", json!(1.0)),
        "links[2].weight",
        "unknown key `weight` (expected one of: type, particles, point, observes)",
    );
}

#[test]
fn unknown_key_in_an_unknown_parameter() {
    scene_error(
        &with(
            "/types/rib/stiffness",
            json!({"min": 1, "max": 2, "start": 1.5}),
        ),
        "types.rib.stiffness.start",
        "unknown key `start`",
    );
}

#[test]
fn missing_dt() {
    scene_error(&without("/dt"), "dt", "missing");
}

#[test]
fn zero_dt() {
    scene_error(
        &with("/dt", json!(0.0)),
        "dt",
        "must be a positive number, got 0",
    );
}

#[test]
fn negative_dt() {
    scene_error(
        &with("/dt", json!(-0.01)),
        "dt",
        "must be a positive number",
    );
}

#[test]
fn negative_mass() {
    scene_error(
        &with("/particles/2/mass", json!(-1.5)),
        "particles[2].mass",
        "must be a positive number, got -1.5",
    );
}

#[test]
fn zero_mass() {
    scene_error(
        &with("/particles/1/mass", json!(0)),
        "particles[1].mass",
        "must be a positive number, got 0",
    );
}

#[test]
fn overflowing_mass_is_a_clear_json_error() {
    // JSON has no NaN or infinity; a literal that overflows f64 is the closest a file gets.
    // serde_json refuses it while parsing, so it is a Format error at its line and column.
    let text = serde_json::to_string_pretty(&base()).unwrap().replacen(
        "\"mass\": 2.0",
        "\"mass\": 1e999",
        1,
    );
    let line = text.lines().position(|l| l.contains("1e999")).unwrap() + 1;
    let start = text.lines().nth(line - 1).unwrap().find("1e999").unwrap() + 1;
    let e = Scene::from_json_str(&text).unwrap_err();
    let CordisError::Format { place, message } = &e else {
        panic!("wrong variant: {e:?}");
    };
    // The column points into the literal (serde_json reports where it stopped reading).
    let col: usize = place
        .strip_prefix(&format!("scene:{line}:"))
        .unwrap_or_else(|| panic!("place {place}"))
        .parse()
        .unwrap();
    assert!((start..start + 5).contains(&col), "{e}");
    assert!(message.contains("number out of range"), "{e}");
    assert!(
        message.contains("must be finite"),
        "the message should say why: {e}"
    );
    assert!(
        !message.contains(" at line "),
        "line and column said twice: {e}"
    );
}

#[test]
fn negative_stiffness() {
    scene_error(
        &with("/types/rib/stiffness", json!(-20.0)),
        "types.rib.stiffness",
        "must be a non-negative number, got -20",
    );
}

#[test]
fn negative_damping() {
    scene_error(
        &with("/types/rib/damping", json!(-0.1)),
        "types.rib.damping",
        "must be a non-negative number",
    );
}

#[test]
fn rest_cos_out_of_range() {
    scene_error(
        &with("/types/bend/rest_cos", json!(1.5)),
        "types.bend.rest_cos",
        "must be a number in [-1, 1], got 1.5",
    );
    scene_error(
        &with("/types/bend/rest_cos", json!(-1.0001)),
        "types.bend.rest_cos",
        "must be a number in [-1, 1]",
    );
}

#[test]
fn rest_cos_bounds_out_of_range() {
    scene_error(
        &with("/types/bend/rest_cos", json!({"min": -2, "max": 0})),
        "types.bend.rest_cos.min",
        "must be a number in [-1, 1], got -2",
    );
}

#[test]
fn zero_range() {
    scene_error(
        &with("/types/near/range", json!(0)),
        "types.near.range",
        "must be a positive number",
    );
}

#[test]
fn index_out_of_range() {
    scene_error(
        &with("/links/1/particles", json!([1, 40])),
        "links[1].particles[1]",
        "particle 40 does not exist",
    );
    let e = read(&with("/links/1/particles", json!([1, 40]))).unwrap_err();
    assert_eq!(
        e.to_string(),
        "links[1].particles[1]: particle 40 does not exist"
    );
}

#[test]
fn negative_or_fractional_index() {
    scene_error(
        &with("/links/0/particles", json!([0, -1])),
        "links[0].particles[1]",
        "expected a particle index (a non-negative integer), got -1",
    );
    scene_error(
        &with("/links/0/particles", json!([0.5, 1])),
        "links[0].particles[0]",
        "expected a particle index",
    );
}

#[test]
fn self_link() {
    scene_error(
        &with("/links/0/particles", json!([1, 1])),
        "links[0].particles[1]",
        "particle 1 is linked to itself",
    );
    scene_error(
        &with("/links/2/particles", json!([0, 1, 0])),
        "links[2].particles[2]",
        "particle 0 is linked to itself",
    );
}

#[test]
fn wrong_arity() {
    scene_error(
        &with("/links/0/particles", json!([0, 1, 2])),
        "links[0].particles",
        "`spring` links join 2 particle(s), got 3",
    );
    scene_error(
        &with("/links/2/particles", json!([0, 1])),
        "links[2].particles",
        "`angle` links join 3 particle(s), got 2",
    );
}

#[test]
fn non_numeric_values() {
    scene_error(
        &with("/particles/0/mass", json!("heavy")),
        "particles[0].mass",
        "expected a number, got a string",
    );
    scene_error(
        &with("/types/rib/stiffness", json!(true)),
        "types.rib.stiffness",
        "expected a number, got a boolean",
    );
    scene_error(
        &with("/particles/1/pos", json!([1, "0", 0])),
        "particles[1].pos[1]",
        "expected a number, got a string",
    );
    scene_error(
        &with("/particles/1/vel", json!([1, 0])),
        "particles[1].vel",
        "expected 3 numbers [x, y, z], got 2",
    );
    scene_error(
        &with("/dt", json!(null)),
        "dt",
        "expected a number, got null",
    );
    scene_error(
        &with("/particles/0/fixed", json!("yes")),
        "particles[0].fixed",
        "expected true or false",
    );
    scene_error(
        &with("/links/0/particles", json!(["0", 1])),
        "links[0].particles[0]",
        "expected a particle index",
    );
}

#[test]
fn a_link_to_a_conditional_type() {
    scene_error(
        &with("/links/0/type", json!("near")),
        "links[0].type",
        "`near` is conditional: its pairs are found from its groups, not listed",
    );
}

#[test]
fn unknown_type_name() {
    scene_error(
        &with("/links/1/type", json!("ribs")),
        "links[1].type",
        "no type named `ribs`",
    );
}

#[test]
fn unknown_parameter_missing_max() {
    scene_error(
        &with("/types/rib/stiffness", json!({"min": 1.0})),
        "types.rib.stiffness",
        "an unknown parameter needs `max`",
    );
}

#[test]
fn unknown_mass_missing_min() {
    scene_error(
        &with("/particles/1/mass", json!({"max": 3.0})),
        "particles[1].mass",
        "an unknown parameter needs `min`",
    );
}

#[test]
fn min_above_max() {
    scene_error(
        &with("/types/rib/stiffness", json!({"min": 100, "max": 10})),
        "types.rib.stiffness",
        "min 100 is above max 10",
    );
}

#[test]
fn init_outside_the_bounds() {
    scene_error(
        &with(
            "/types/rib/stiffness",
            json!({"min": 1, "max": 10, "init": 20}),
        ),
        "types.rib.stiffness.init",
        "20 is outside [1, 10]",
    );
}

#[test]
fn missing_required_parameter() {
    let mut v = base();
    v["types"]["rib"]
        .as_object_mut()
        .unwrap()
        .remove("rest_length");
    scene_error(&v, "types.rib", "`spring` types need `rest_length`");
}

#[test]
fn conditional_groups() {
    scene_error(
        &with("/types/near/groups", json!([])),
        "types.near.groups",
        "names one or two groups, got 0",
    );
    scene_error(
        &with("/types/near/groups", json!(["a", "b", "c"])),
        "types.near.groups",
        "names one or two groups, got 3",
    );
    scene_error(
        &with("/types/near/groups", json!("gas")),
        "types.near.groups",
        "expected an array of group names",
    );
}

#[test]
fn wrong_format_tag() {
    scene_error(
        &with("/format", json!("cordis-scene/2")),
        "format",
        "expected \"cordis-scene/1\"",
    );
}

#[test]
fn max_elongation_must_be_positive() {
    scene_error(
        &with("/types/rib/max_elongation", json!(0)),
        "types.rib.max_elongation",
        "must be a positive number",
    );
}

#[test]
fn an_unknown_max_elongation_box_must_be_positive() {
    scene_error(
        &with("/types/rib/max_elongation", json!({"min": 0, "max": 0.5})),
        "types.rib.max_elongation.min",
        "must be a positive number, got 0",
    );
    scene_error(
        &with(
            "/types/rib/max_elongation",
            json!({"min": -0.2, "max": -0.1}),
        ),
        "types.rib.max_elongation.min",
        "must be a positive number, got -0.2",
    );
}

#[test]
fn damping_quadratic_must_not_be_negative() {
    scene_error(
        &with("/types/rib/damping_quadratic", json!(-0.5)),
        "types.rib.damping_quadratic",
        "must be a non-negative number, got -0.5",
    );
    scene_error(
        &with("/types/rib/damping_quadratic", json!({"min": -1, "max": 2})),
        "types.rib.damping_quadratic.min",
        "must be a non-negative number, got -1",
    );
}

#[test]
fn no_input_panics() {
    // A sweep of junk in every slot of the base scene: errors, never a panic.
    let junk = [
        json!(null),
        json!(-1),
        json!(1e308),
        json!(u64::MAX),
        json!("x"),
        json!([]),
        json!({}),
        json!([1, 2, 3]),
        json!({"min": 1, "max": 2}),
    ];
    let mut pointers = Vec::new();
    fn walk(v: &Value, at: String, out: &mut Vec<String>) {
        match v {
            Value::Object(o) => {
                for (k, x) in o {
                    walk(x, format!("{at}/{k}"), out);
                }
            }
            Value::Array(a) => {
                for (k, x) in a.iter().enumerate() {
                    walk(x, format!("{at}/{k}"), out);
                }
            }
            _ => {}
        }
        if !at.is_empty() {
            out.push(at);
        }
    }
    walk(&base(), String::new(), &mut pointers);
    assert!(pointers.len() > 40);
    for at in &pointers {
        for j in &junk {
            let v = with(at, j.clone());
            if let Err(e) = read(&v) {
                assert!(!e.to_string().contains('\n'), "{e}");
            }
            if let Ok(s) = read(&v) {
                // Whatever is accepted simulates without panicking.
                let _ = s.simulate(3);
            }
        }
    }
}

/// The per-part checks an editor uses (`validate_globals`, `validate_particle`,
/// `validate_type`) give the error `validate` gives for a fault in that part, and accept the
/// parts that are fine.
#[test]
fn partial_validation_agrees_with_validate() {
    let good = read(&base()).unwrap();
    good.validate_globals().unwrap();
    for i in 0..good.num_particles() {
        good.validate_particle(i).unwrap();
    }
    for t in 0..good.types.len() {
        good.validate_type(t).unwrap();
    }
    let same = |s: &Scene, part: cordis_core::Result<()>, place: &str| {
        let (whole, part) = (s.validate().unwrap_err(), part.unwrap_err());
        assert_eq!(whole.to_string(), part.to_string());
        assert!(whole.to_string().starts_with(place), "{whole}");
    };
    let mut s = good.clone();
    s.dt = -0.5;
    same(&s, s.validate_globals(), "dt:");
    let mut s = good.clone();
    s.gravity[1] = f64::NAN;
    same(&s, s.validate_globals(), "gravity[1]:");
    let mut s = good.clone();
    s.particles[2].mass = cordis_core::Param::Known(0.0);
    same(&s, s.validate_particle(2), "particles[2].mass:");
    s.validate_particle(1).unwrap();
    let mut s = good.clone();
    s.particles[1].vel[2] = f64::INFINITY;
    same(&s, s.validate_particle(1), "particles[1].vel[2]:");
    let mut s = good.clone();
    s.types[1].params[0] = cordis_core::Param::Known(-2.0);
    let bend = s.types[1].name.clone();
    same(&s, s.validate_type(1), &format!("types.{bend}."));
    s.validate_type(0).unwrap();
}

/// Issue 17: `"stiffness": 20, "stiffness": 1e6` read as 1e6 without a word (serde_json keeps
/// the last value); now refused, naming the key, its line and column.
#[test]
fn a_duplicate_json_key_is_refused_naming_the_key_and_its_place() {
    let text = "{\n  \"format\": \"cordis-scene/1\",\n  \"dt\": 0.01,\n  \"particles\": [{\"mass\": 1, \"pos\": [0, 0, 0]}],\n  \"types\": {\"rib\": {\"kind\": \"spring\", \"stiffness\": 20.0,\n    \"stiffness\": 1e6}},\n  \"links\": []\n}";
    let e = Scene::from_json_str(text).unwrap_err().to_string();
    assert!(
        e.starts_with("scene:6:15: invalid JSON: duplicate key `stiffness`"),
        "{e}"
    );
    // At the top level too, and in a file (the place starts with its name).
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("twice.json");
    std::fs::write(&path, "{\"dt\": 0.01,\n \"dt\": 0.02}").unwrap();
    let place = format!("{}:2:5", path.display());
    check(
        Scene::from_json_path(&path),
        &place,
        "duplicate key `dt`",
        false,
    );
    // Equal keys in different objects are not duplicates.
    assert!(read(&base()).is_ok());
}

/// Issue 17: a conditional type naming a group no particle is in (a misspelt `gaz`) left the
/// scene without that force, silently.
#[test]
fn a_conditional_group_no_particle_has_is_an_error_naming_the_groups() {
    scene_error(
        &with("/types/near/groups", json!(["gaz"])),
        "types.near.groups",
        "no particle is in group `gaz` (the groups are gas): the type would never link a pair",
    );
    scene_error(
        &with("/types/near/groups", json!(["gas", "wall"])),
        "types.near.groups",
        "no particle is in group `wall`",
    );
}
