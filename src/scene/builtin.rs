//! Built-in scenes (`cradle scenes`): the seed document's three examples and
//! the classic 5-ball cradle. Each is a TOML text, parsed like any file.

use super::SceneSpec;
use crate::error::{InputError, Source};

pub struct Builtin {
    pub name: &'static str,
    pub summary: &'static str,
    pub toml: &'static str,
}

impl Builtin {
    pub fn spec(&self) -> Result<SceneSpec, InputError> {
        SceneSpec::parse(&Source::new(
            format!("built-in scene {}", self.name),
            self.toml,
        ))
    }
}

pub const BUILTINS: &[Builtin] = &[
    Builtin {
        name: "seed-two-lifted",
        summary:
            "seed §2: two balls lifted 5 cm into a 5-ball cradle (free line, impact at √(2gh))",
        toml: "balls = 5\n[launch]\nballs = 2\nheight = 0.05\n",
    },
    Builtin {
        name: "seed-glued-pair-into-one",
        summary: "seed §3.2: a glued pair at 1 m/s into one ball (textbook: 1/3 and 4/3 of v)",
        toml: "balls = 3\nglue = \"=-\"\nvelocity = [1.0, 1.0, 0.0]\n",
    },
    Builtin {
        name: "seed-glued-pair-into-three",
        summary: "seed §4: a glued pair at 0.8 m/s into three touching balls",
        toml: "balls = 5\nglue = \"=---\"\nvelocity = [0.8, 0.8, 0.0, 0.0, 0.0]\n",
    },
    Builtin {
        name: "cradle-1",
        summary: "5-ball cradle, 1 ball launched at 1 m/s",
        toml: "balls = 5\n[launch]\nballs = 1\nvelocity = 1.0\n",
    },
    Builtin {
        name: "cradle-2",
        summary: "5-ball cradle, 2 balls launched at 1 m/s",
        toml: "balls = 5\n[launch]\nballs = 2\nvelocity = 1.0\n",
    },
    Builtin {
        name: "cradle-3",
        summary: "5-ball cradle, 3 balls launched at 1 m/s",
        toml: "balls = 5\n[launch]\nballs = 3\nvelocity = 1.0\n",
    },
];

pub fn find(name: &str) -> Option<&'static Builtin> {
    BUILTINS.iter().find(|b| b.name == name)
}

pub fn names() -> Vec<&'static str> {
    BUILTINS.iter().map(|b| b.name).collect()
}

#[cfg(test)]
mod tests {
    #[test]
    fn every_builtin_validates() {
        for b in super::BUILTINS {
            b.spec()
                .unwrap()
                .validate()
                .unwrap_or_else(|e| panic!("{}: {e}", b.name));
        }
    }
}
