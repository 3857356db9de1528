//! Units used by the variable table: SI base-unit exponents and display units.
//! The XML renderer writes these as `<UnitDefinitions>`. Numbers in messages:
//! [`readable`] (the physics crate's, which writes its own messages with it).

pub use crate::physics::readable;

/// Exponents of kg, m, s, A, K, mol, cd, rad.
pub type BaseExponents = [i8; 8];

pub struct DisplayUnit {
    pub name: &'static str,
    /// display value = factor * SI value + offset
    pub factor: f64,
    pub offset: f64,
}

pub struct Unit {
    pub name: &'static str,
    pub base: BaseExponents,
    pub display: &'static [DisplayUnit],
}

const fn d(name: &'static str, factor: f64) -> DisplayUnit {
    DisplayUnit { name, factor, offset: 0.0 }
}

//                     kg  m  s  A  K mol cd rad
pub static UNITS: &[Unit] = &[
    Unit { name: "s", base: [0, 0, 1, 0, 0, 0, 0, 0], display: &[d("ms", 1e3)] },
    Unit { name: "A", base: [0, 0, 0, 1, 0, 0, 0, 0], display: &[d("mA", 1e3)] },
    Unit { name: "V", base: [1, 2, -3, -1, 0, 0, 0, 0], display: &[] },
    Unit { name: "m", base: [0, 1, 0, 0, 0, 0, 0, 0], display: &[d("mm", 1e3), d("um", 1e6)] },
    Unit { name: "m2", base: [0, 2, 0, 0, 0, 0, 0, 0], display: &[] },
    Unit { name: "m3/s", base: [0, 3, -1, 0, 0, 0, 0, 0], display: &[d("L/min", 6e4)] },
    Unit { name: "m2/s", base: [0, 2, -1, 0, 0, 0, 0, 0], display: &[] },
    Unit { name: "Hz", base: [0, 0, -1, 0, 0, 0, 0, 0], display: &[] },
    Unit { name: "H", base: [1, 2, -2, -2, 0, 0, 0, 0], display: &[] },
    Unit { name: "Ohm", base: [1, 2, -3, -2, 0, 0, 0, 0], display: &[] },
    Unit { name: "V/A", base: [1, 2, -3, -2, 0, 0, 0, 0], display: &[] },
    Unit { name: "V/(A.s)", base: [1, 2, -4, -2, 0, 0, 0, 0], display: &[] },
    Unit { name: "V/s", base: [1, 2, -4, -1, 0, 0, 0, 0], display: &[d("V/us", 1e-6)] },
    Unit { name: "V.s/m", base: [1, 1, -2, -1, 0, 0, 0, 0], display: &[] },
    Unit { name: "N.m/A", base: [1, 2, -2, -1, 0, 0, 0, 0], display: &[] },
    Unit { name: "N.m/m", base: [1, 1, -2, 0, 0, 0, 0, 0], display: &[] },
    Unit { name: "kg", base: [1, 0, 0, 0, 0, 0, 0, 0], display: &[] },
    Unit { name: "N", base: [1, 1, -2, 0, 0, 0, 0, 0], display: &[] },
    Unit { name: "Pa", base: [1, -1, -2, 0, 0, 0, 0, 0], display: &[d("bar", 1e-5)] },
    Unit { name: "m/s", base: [0, 1, -1, 0, 0, 0, 0, 0], display: &[d("mm/s", 1e3)] },
    Unit { name: "m3", base: [0, 3, 0, 0, 0, 0, 0, 0], display: &[d("cm3", 1e6)] },
    Unit { name: "N/m", base: [1, 0, -2, 0, 0, 0, 0, 0], display: &[] },
    Unit { name: "N.s/m", base: [1, 0, -1, 0, 0, 0, 0, 0], display: &[] },
    Unit { name: "m3/(s.Pa)", base: [-1, 4, 1, 0, 0, 0, 0, 0], display: &[] },
    Unit { name: "A.s/m3", base: [0, -3, 1, 1, 0, 0, 0, 0], display: &[] },
    Unit { name: "A/m3", base: [0, -3, 0, 1, 0, 0, 0, 0], display: &[] },
    Unit { name: "A.s2/m3", base: [0, -3, 2, 1, 0, 0, 0, 0], display: &[] },
    Unit { name: "A/m", base: [0, -1, 0, 1, 0, 0, 0, 0], display: &[] },
    Unit { name: "A/(m.s)", base: [0, -1, -1, 1, 0, 0, 0, 0], display: &[] },
    Unit { name: "A.s/m", base: [0, -1, 1, 1, 0, 0, 0, 0], display: &[] },
    Unit { name: "Pa/A", base: [1, -1, -2, -1, 0, 0, 0, 0], display: &[d("bar/mA", 1e-8)] },
];

pub fn unit(name: &str) -> Option<&'static Unit> {
    UNITS.iter().find(|u| u.name == name)
}

#[cfg(test)]
mod tests {
    use crate::variables::VARIABLES;

    #[test]
    fn every_variable_unit_and_display_unit_is_defined() {
        for v in VARIABLES.iter() {
            if let Some(name) = v.unit {
                let u = super::unit(name)
                    .unwrap_or_else(|| panic!("{}: unit {name} undefined", v.name));
                if let Some(du) = v.display_unit {
                    assert!(
                        u.display.iter().any(|d| d.name == du),
                        "{}: display unit {du}",
                        v.name
                    );
                }
            } else {
                assert!(v.display_unit.is_none());
            }
        }
    }
}
