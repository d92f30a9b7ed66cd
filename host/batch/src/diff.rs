//! Which setting differs: the first field where two JSON values disagree, for messages such as
//! "`exec.particles` is 4 there and 5 here".

/// The first field where two JSON values differ (`exec.particles`), with both values.
pub fn first_difference(
    a: &serde_json::Value,
    b: &serde_json::Value,
    at: &str,
) -> (String, String, String) {
    if let (Some(ma), Some(mb)) = (a.as_object(), b.as_object()) {
        for (k, va) in ma {
            match mb.get(k) {
                Some(vb) if vb == va => {}
                Some(vb) => return first_difference(va, vb, &format!("{at}.{k}")),
                None => return (format!("{at}.{k}"), va.to_string(), "(absent)".into()),
            }
        }
        if let Some((k, vb)) = mb.iter().find(|(k, _)| !ma.contains_key(*k)) {
            return (format!("{at}.{k}"), "(absent)".into(), vb.to_string());
        }
    }
    (at.to_string(), a.to_string(), b.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_differing_field_is_named() {
        let a = serde_json::json!({"exec": {"particles": 4, "iters": 8}, "task": "card"});
        let b = serde_json::json!({"exec": {"particles": 5, "iters": 8}, "task": "card"});
        assert_eq!(
            first_difference(&a, &b, "settings"),
            ("settings.exec.particles".into(), "4".into(), "5".into())
        );
        let c = serde_json::json!({"task": "card"});
        assert_eq!(first_difference(&c, &a, "s").0, "s.exec");
    }
}
