//! JSON for people and scripts: numbers that went through `f32` (positions, radii, scene
//! values) written as their shortest `f32` decimal (`0.1`, not `0.10000000149011612`).

use serde::Serialize;

/// `value` as pretty JSON, every number that is exactly an `f32` written as that `f32`'s
/// shortest decimal; other numbers unchanged.
pub fn to_pretty<T: Serialize + ?Sized>(value: &T) -> anyhow::Result<String> {
    let mut v = serde_json::to_value(value)?;
    tidy_floats(&mut v);
    Ok(serde_json::to_string_pretty(&v)?)
}

/// Rewrites, in place, every float of `v` that is exactly representable as an `f32` to the
/// double nearest that `f32`'s shortest decimal.
pub fn tidy_floats(v: &mut serde_json::Value) {
    match v {
        serde_json::Value::Number(n) if n.is_f64() => {
            if let Some(x) = n.as_f64() {
                let single = x as f32;
                if f64::from(single) == x
                    && let Ok(shortest) = single.to_string().parse::<f64>()
                    && let Some(m) = serde_json::Number::from_f64(shortest)
                {
                    *n = m;
                }
            }
        }
        serde_json::Value::Array(a) => a.iter_mut().for_each(tidy_floats),
        serde_json::Value::Object(o) => o.values_mut().for_each(tidy_floats),
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn single_precision_values_print_short_and_doubles_keep_their_digits() {
        let text = to_pretty(&serde_json::json!({ "cell_m": 0.1f32, "pi": std::f64::consts::PI, "n": 3 }))
            .expect("serialises");
        assert!(text.contains("\"cell_m\": 0.1,"), "{text}");
        assert!(text.contains("3.141592653589793"), "{text}");
        assert!(text.contains("\"n\": 3"), "{text}");
    }
}
