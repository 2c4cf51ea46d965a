//! Named choices: one table of names per fieldless enum gives its `Display` and `FromStr`
//! (command-line values, messages), so a setting's spelling is written once, beside the type
//! that owns it.

/// Implements `Display` and `FromStr` (error: a message listing the names) for a fieldless enum
/// from one `Variant => "name"` table. `$what` names the setting in the error.
#[macro_export]
macro_rules! named_choices {
    ($ty:ty, $what:literal, { $($variant:path => $name:literal),+ $(,)? }) => {
        impl ::std::fmt::Display for $ty {
            fn fmt(&self, f: &mut ::std::fmt::Formatter<'_>) -> ::std::fmt::Result {
                f.write_str(match self { $($variant => $name),+ })
            }
        }
        impl ::std::str::FromStr for $ty {
            type Err = ::std::string::String;
            fn from_str(s: &str) -> ::std::result::Result<Self, Self::Err> {
                match s {
                    $($name => Ok($variant),)+
                    other => Err(format!("unknown {} '{}' (one of: {})", $what, other, [$($name),+].join(", "))),
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
    }
}
