//! Named choices: one table of names per fieldless enum gives its `Display` and `FromStr`
//! (command-line values, messages), so a setting's spelling is written once, beside the type
//! that owns it.

/// Implements `Display` and `FromStr` (error: a message listing the names) for a fieldless enum
/// from one `Variant => "name"` table. `$what` names the setting in the error. The long form,
/// `..., ignore_case, aliases { "other" => Variant }`, also accepts any letter case and extra
/// spellings (parsed, never printed).
#[macro_export]
macro_rules! named_choices {
    ($ty:ty, $what:literal, { $($variant:path => $name:literal),+ $(,)? }) => {
        $crate::named_choices!(@impl $ty, $what, |s| s, { $($variant => $name),+ }, {});
    };
    ($ty:ty, $what:literal, { $($variant:path => $name:literal),+ $(,)? }, ignore_case, aliases { $($alias:literal => $avariant:path),* $(,)? }) => {
        $crate::named_choices!(@impl $ty, $what, |s| s.to_ascii_lowercase(), { $($variant => $name),+ }, { $($alias => $avariant),* });
    };
    (@impl $ty:ty, $what:literal, |$s:ident| $key:expr, { $($variant:path => $name:literal),+ }, { $($alias:literal => $avariant:path),* }) => {
        impl ::std::fmt::Display for $ty {
            fn fmt(&self, f: &mut ::std::fmt::Formatter<'_>) -> ::std::fmt::Result {
                f.write_str(match self { $($variant => $name),+ })
            }
        }
        impl ::std::str::FromStr for $ty {
            type Err = ::std::string::String;
            fn from_str($s: &str) -> ::std::result::Result<Self, Self::Err> {
                match ::std::convert::AsRef::<str>::as_ref(&$key) {
                    $($name => Ok($variant),)+
                    $($alias => Ok($avariant),)*
                    _ => Err(format!("unknown {} '{}' (one of: {})", $what, $s, [$($name),+].join(", "))),
                }
            }
        }
    };
}

#[cfg(test)]
mod tests {
    #[derive(Debug, Clone, Copy, PartialEq)]
    enum Colour {
        Red,
        Green,
    }
    crate::named_choices!(Colour, "colour", { Colour::Red => "red", Colour::Green => "green" });

    #[test]
    fn names_round_trip_and_errors_list_them() {
        for c in [Colour::Red, Colour::Green] {
            assert_eq!(c.to_string().parse::<Colour>(), Ok(c));
        }
        assert_eq!("blue".parse::<Colour>().unwrap_err(), "unknown colour 'blue' (one of: red, green)");
        assert!("Red".parse::<Colour>().is_err());
    }

    #[derive(Debug, Clone, Copy, PartialEq)]
    enum Shape {
        Round,
        Square,
    }
    crate::named_choices!(Shape, "shape", { Shape::Round => "round", Shape::Square => "square" }, ignore_case, aliases { "circle" => Shape::Round });

    #[test]
    fn the_long_form_ignores_case_and_takes_aliases() {
        assert_eq!("SQUARE".parse::<Shape>(), Ok(Shape::Square));
        assert_eq!("Circle".parse::<Shape>(), Ok(Shape::Round));
        assert_eq!(Shape::Round.to_string(), "round");
        assert_eq!("Oval".parse::<Shape>().unwrap_err(), "unknown shape 'Oval' (one of: round, square)");
    }
}
