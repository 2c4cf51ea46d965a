//! scripts/check-k8s-manifest.sh on hand-written manifests: a valid Indexed Job is accepted;
//! a schema error, an unknown field and another kind are refused with the validator's message.

use std::path::{Path, PathBuf};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/k8s").join(name)
}

#[test]
fn an_indexed_job_is_accepted() {
    let Some(v) = gs_testdata::k8s_validator!() else { return };
    v.check(&fixture("indexed-job.yaml")).unwrap();
}

#[test]
fn completions_as_a_string_is_refused() {
    let Some(v) = gs_testdata::k8s_validator!() else { return };
    let e = v.check(&fixture("bad-completions.yaml")).unwrap_err();
    assert!(e.contains("spec.completions") && e.contains("integer"), "{e}");
}

#[test]
fn an_unknown_spec_field_is_refused() {
    let Some(v) = gs_testdata::k8s_validator!() else { return };
    let e = v.check(&fixture("unknown-field.yaml")).unwrap_err();
    assert!(e.contains("parallelsim"), "{e}");
}

#[test]
fn another_kind_and_non_yaml_are_refused() {
    let Some(v) = gs_testdata::k8s_validator!() else { return };
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("k8s-kinds");
    std::fs::create_dir_all(&dir).unwrap();
    let cm = dir.join("configmap.yaml");
    std::fs::write(&cm, "apiVersion: v1\nkind: ConfigMap\nmetadata:\n  name: x\n").unwrap();
    let e = v.check(&cm).unwrap_err();
    assert!(e.contains("v1 ConfigMap, not a batch/v1 Job"), "{e}");
    let bad = dir.join("broken.yaml");
    std::fs::write(&bad, "spec: [\n").unwrap();
    let e = v.check(&bad).unwrap_err();
    assert!(e.contains("is not YAML"), "{e}");
    let e = v.check(&dir.join("missing.yaml")).unwrap_err();
    assert!(e.contains("cannot read"), "{e}");
}
