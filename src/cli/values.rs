//! Parsers of flag values shared by the commands: an error target, a frame
//! range, a pixel, seconds, a colour.

pub fn parse_error_target(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 && v < 1.0 => Ok(v),
        _ => Err(format!(
            "expected an RMSE on linear values between 0 and 1 (e.g. 0.005), found `{s}`"
        )),
    }
}

pub fn parse_range(s: &str) -> Result<[u32; 2], String> {
    let parsed = s
        .split_once('-')
        .and_then(|(a, b)| Some([a.trim().parse().ok()?, b.trim().parse().ok()?]));
    match parsed {
        Some([a, b]) if a <= b => Ok([a, b]),
        _ => Err(format!(
            "expected FIRST-LAST with FIRST <= LAST (e.g. 0-99), found `{s}`"
        )),
    }
}

pub fn parse_pixel(s: &str) -> Result<[u32; 2], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    match parts.as_slice() {
        [x, y] => match (x.parse(), y.parse()) {
            (Ok(x), Ok(y)) => Ok([x, y]),
            _ => Err(format!(
                "expected X,Y as two whole numbers (e.g. 320,240), found `{s}`"
            )),
        },
        _ => Err(format!("expected X,Y (e.g. 320,240), found `{s}`")),
    }
}

pub fn parse_seconds(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 && v <= 1e6 => Ok(v),
        _ => Err(format!(
            "expected a number of seconds above 0 (e.g. 120), found `{s}`"
        )),
    }
}

/// X,Y,Z: a point or direction, any finite numbers.
pub fn parse_xyz(s: &str) -> Result<[f64; 3], String> {
    let values: Result<Vec<f64>, _> = s.split(',').map(|p| p.trim().parse::<f64>()).collect();
    match values {
        Ok(v) if v.len() == 3 && v.iter().all(|c| c.is_finite()) => Ok([v[0], v[1], v[2]]),
        _ => Err(format!(
            "expected X,Y,Z as three finite numbers (e.g. 0,1,5), found `{s}`"
        )),
    }
}

pub fn parse_rgb(s: &str) -> Result<[f32; 3], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let values: Result<Vec<f32>, _> = parts.iter().map(|p| p.parse::<f32>()).collect();
    match values {
        Ok(v) if v.len() == 3 && v.iter().all(|c| (0.0..=1.0).contains(c)) => {
            Ok([v[0], v[1], v[2]])
        }
        _ => Err(format!(
            "expected R,G,B with each in [0, 1] (e.g. 0,0,0 for black), found `{s}`"
        )),
    }
}
