//! The enumerated values of the command line's options, as clap `ValueEnum`s spelt as the user
//! types them, each mapped to the library type it stands for: the library crates know no clap,
//! and clap then checks every value and lists the possible ones in `--help` and its errors.
//!
//! Variants carry no doc comments: clap would print them in `--help` as a second description of
//! values the option's own help already explains.

use clap::ValueEnum;
use pxpl5_radiosity::shot::Method;
use pxpl5_radiosity::views::{EdgeRule, HemisphereDepth};
use pxpl5_renderer::Fidelity;
use pxpl5_ring::RingLevel;

/// `--fidelity` of `run` and `radiosity`: one Renderer fidelity level.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum FidelityArg {
    Bit,
    // `word`, the level's name until it was renamed, stays a hidden alias for existing scripts.
    #[value(alias = "word")]
    Integer,
    Sparse,
    Timing,
}

impl From<FidelityArg> for Fidelity {
    fn from(f: FidelityArg) -> Fidelity {
        match f {
            FidelityArg::Bit => Fidelity::Bit,
            FidelityArg::Integer => Fidelity::Integer,
            FidelityArg::Sparse => Fidelity::Sparse,
            FidelityArg::Timing => Fidelity::Timing,
        }
    }
}

/// `--ring-level` of `run` and `radiosity`: how the ring is simulated.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ValueEnum)]
pub enum RingLevelArg {
    #[default]
    Token,
    Message,
}

impl From<RingLevelArg> for RingLevel {
    fn from(r: RingLevelArg) -> RingLevel {
        match r {
            RingLevelArg::Token => RingLevel::Token,
            RingLevelArg::Message => RingLevel::Message,
        }
    }
}

/// `bench renderer --fidelity`: one level, or every level in turn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BenchFidelity {
    Bit,
    #[value(alias = "word")]
    Integer,
    Sparse,
    All,
}

impl BenchFidelity {
    /// The levels to measure, in order.
    pub fn levels(self) -> Vec<Fidelity> {
        match self {
            BenchFidelity::Bit => vec![Fidelity::Bit],
            BenchFidelity::Integer => vec![Fidelity::Integer],
            BenchFidelity::Sparse => vec![Fidelity::Sparse],
            BenchFidelity::All => vec![Fidelity::Bit, Fidelity::Integer, Fidelity::Sparse],
        }
    }
}

/// `--method` of `radiosity` and `bench renderer`: one form-factor method, or both in turn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Methods {
    Hemisphere,
    Hemicube,
    Both,
}

impl Methods {
    /// The methods to run, in order: the hemisphere first, as the ratio's denominator.
    pub fn methods(self) -> Vec<Method> {
        match self {
            Methods::Hemisphere => vec![Method::Hemisphere],
            Methods::Hemicube => vec![Method::Hemicube],
            Methods::Both => vec![Method::Hemisphere, Method::Hemicube],
        }
    }
}

/// `formfactor --method`: the exact contour formula, or a method on the machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum FormFactorMethod {
    Exact,
    Hemisphere,
    Hemicube,
}

impl FormFactorMethod {
    /// The method on the machine; `None` for the exact formula, which needs no machine.
    pub fn on_machine(self) -> Option<Method> {
        match self {
            FormFactorMethod::Exact => None,
            FormFactorMethod::Hemisphere => Some(Method::Hemisphere),
            FormFactorMethod::Hemicube => Some(Method::Hemicube),
        }
    }
}

/// `radiosity --edge-rule`: how a hemisphere edge's two sign flags become enable.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum EdgeRuleArg {
    SignOfC,
    Seed,
}

impl From<EdgeRuleArg> for EdgeRule {
    fn from(e: EdgeRuleArg) -> EdgeRule {
        match e {
            EdgeRuleArg::SignOfC => EdgeRule::SignOfC,
            EdgeRuleArg::Seed => EdgeRule::Seed,
        }
    }
}

/// `radiosity --delta`: the hemisphere's delta form factors.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Delta {
    Exact,
    Seed,
}

impl Delta {
    /// Whether the delta form factors are exact disk areas (else the seed's integral rule).
    pub fn exact(self) -> bool {
        self == Delta::Exact
    }
}

/// `radiosity --depth`: how depth is compared on the hemisphere.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum DepthArg {
    Taylor,
    StoredW,
}

impl From<DepthArg> for HemisphereDepth {
    fn from(d: DepthArg) -> HemisphereDepth {
        match d {
            DepthArg::Taylor => HemisphereDepth::Taylor,
            DepthArg::StoredW => HemisphereDepth::StoredW,
        }
    }
}

/// `run --program`: the programs `pxpl5 run` can run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ProgramArg {
    Polygons,
}
