//! Small dense symmetric positive definite solves (`n × n`, row-major), in place: the reduced
//! systems of the online paths (`rom`) and the MLS moment matrices (`meshless::mls`). No
//! allocation, no threads.

/// Overwrites the lower triangle of `a` (`n × n`, row-major) with its Cholesky factor `L`
/// (`a = L Lᵀ`). Fails with the index of the first pivot that is not positive (or not
/// finite): the matrix is not positive definite.
pub fn cholesky(a: &mut [f64], n: usize) -> Result<(), usize> {
    cholesky_relative(a, n, 0.0)
}

/// [`cholesky`], also failing when a squared pivot falls to `relative` times the largest
/// diagonal entry or below: the matrix is numerically singular (e.g. an MLS moment matrix of
/// nodes nearly on one line).
pub fn cholesky_relative(a: &mut [f64], n: usize, relative: f64) -> Result<(), usize> {
    let floor = relative * (0..n).map(|i| a[i * n + i].abs()).fold(0.0, f64::max);
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        if d.is_nan() || d <= floor || d <= 0.0 || !d.is_finite() {
            return Err(j);
        }
        let d = d.sqrt();
        a[j * n + j] = d;
        for i in j + 1..n {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = s / d;
        }
    }
    Ok(())
}

/// Solves `L Lᵀ x = b` in place with the factor of [`cholesky`].
pub fn cholesky_solve(l: &[f64], n: usize, b: &mut [f64]) {
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i * n + k] * b[k];
        }
        b[i] = s / l[i * n + i];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= l[k * n + i] * b[k];
        }
        b[i] = s / l[i * n + i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_an_spd_system_and_names_the_failing_pivot() {
        let a0 = [4.0, 2.0, 0.4, 2.0, 5.0, 1.0, 0.4, 1.0, 3.0];
        let mut l = a0;
        cholesky(&mut l, 3).unwrap();
        let x = [1.0, -2.0, 0.5];
        let mut b: Vec<f64> = (0..3).map(|i| (0..3).map(|j| a0[i * 3 + j] * x[j]).sum()).collect();
        cholesky_solve(&l, 3, &mut b);
        assert!(b.iter().zip(x).all(|(a, b)| (a - b).abs() < 1e-14));
        let mut indefinite = [1.0, 2.0, 2.0, 1.0];
        assert_eq!(cholesky(&mut indefinite, 2), Err(1));
        let mut nan = [f64::NAN];
        assert_eq!(cholesky(&mut nan, 1), Err(0));
        // positive but negligible against the diagonal: singular with a relative floor
        let mut nearly = [1.0, 1.0, 1.0, 1.0 + 1e-14];
        assert!(cholesky(&mut nearly.clone(), 2).is_ok());
        assert_eq!(cholesky_relative(&mut nearly, 2, 1e-12), Err(1));
    }
}
