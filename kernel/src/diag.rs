//! Diagnostics: every error and warning the kernel produces, with where it comes from and a
//! stable code ([`DiagCode`]) saying what it is about.

use std::fmt;

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Severity {
    /// Informational message (e.g. an inserted arc reported because R339 is negative, SPEC §4.3).
    Info,
    /// The program may run, but the machinist should look (e.g. R397 equidistant check, SPEC §4.5).
    Warning,
    /// The program must not run.
    Error,
}

/// Declares [`DiagCode`] and its string table in one place, so a variant cannot lack its
/// stable string.
macro_rules! diag_codes {
    ($($(#[$doc:meta])* $name:ident = $s:literal,)*) => {
        /// What a [`Diagnostic`] is about, as a stable code: tests and HMIs match the code,
        /// the message stays free to improve. The string form ([`DiagCode::as_str`],
        /// `lower_snake_case`) is part of the API (`Diagnostic.code` in cnc.proto) and is
        /// listed in docs/api.md ("Diagnostic codes"): a code is never renamed or reused.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum DiagCode {
            $($(#[$doc])* $name,)*
        }

        impl DiagCode {
            /// Every code, in declaration order.
            pub const ALL: &'static [DiagCode] = &[$(DiagCode::$name,)*];

            /// The stable string form.
            pub const fn as_str(self) -> &'static str {
                match self {
                    $(DiagCode::$name => $s,)*
                }
            }
        }
    };
}

// A table: one line per code reads better whole than split.
diag_codes! {
    // ---- program text: words (SPEC §2) ----
    /// A number with too many digits or decimals.
    NumberMalformed = "number_malformed",
    /// A character the language does not have here.
    UnexpectedCharacter = "unexpected_character",
    /// An address letter without its value.
    WordWithoutValue = "word_without_value",
    /// An address the language does not have.
    UnknownAddress = "unknown_address",
    /// A word taking a whole number written with a fraction or decimal point.
    WordNotWhole = "word_not_whole",
    /// A word's value outside its range (G, M, D, &, N, I of the dynamic set).
    WordOutOfRange = "word_out_of_range",
    /// The same word twice in one block.
    WordTwice = "word_twice",
    /// N that is not the first word of the block.
    BlockNumberNotFirst = "block_number_not_first",
    /// Two G functions of one modal group in one block.
    GGroupConflict = "g_group_conflict",
    /// Two M functions of one group (spindle, feed scale, gear) in one block.
    MGroupConflict = "m_group_conflict",
    /// More than 4 M functions in one block.
    TooManyMFunctions = "too_many_m_functions",
    /// A G function this controller does not have.
    UnknownGFunction = "unknown_g_function",
    /// G18/G19 on a machine without the third axis.
    PlaneNeedsAxis = "plane_needs_axis",
    // ---- the ISO / RS274-NGC dialect (docs/language.md) ----
    /// A word, G or M code of RS274-NGC that cncd does not run (the message names it).
    IsoUnsupported = "iso_unsupported",
    /// An expression written wrong (brackets, operator, function name).
    ExpressionSyntax = "expression_syntax",
    /// An expression whose value is undefined (division by zero, SQRT of a negative, ...).
    ExpressionDomain = "expression_domain",
    /// A numbered parameter outside #1..#5602, or a read-only one written.
    IsoParamOutOfRange = "iso_param_out_of_range",
    /// An O-word that does not match its opening (endwhile without while, ...).
    OWordMismatch = "oword_mismatch",
    /// A call of a subroutine that the program does not define.
    SubroutineUnknown = "subroutine_unknown",
    /// A loop that ran more iterations than the interpreter allows, or calls nested too deep.
    LoopLimit = "loop_limit",
    /// The program source cannot go back to a line (a loop or a call needs it).
    SourceCannotSeek = "source_cannot_seek",
    /// A canned cycle without a word it needs (R, Z, Q ...), or with a wrong value.
    CycleWord = "cycle_word",
    /// An arc written with R whose end point is farther than 2·R from its start, or helical
    /// turns P other than 1.
    ArcRadiusForm = "arc_radius_form",
    /// Two words of a modal group (or two motion words using axes) in one block.
    IsoModalConflict = "iso_modal_conflict",
    /// A tool number not in the offset table (T, H or D).
    ToolNotInTable = "tool_not_in_table",
    /// A message of the program, `(MSG, …)` (information).
    ProgramMessage = "program_message",
    // ---- program parameters R0..R94 ----
    /// A parameter number outside R0..R94.
    ParamOutOfRange = "param_out_of_range",
    /// An `R<n>=value` assignment written wrong.
    ParamAssignmentSyntax = "param_assignment_syntax",
    /// A parameter used before it was assigned.
    ParamUnassigned = "param_unassigned",
    /// More than 16 parameter assignments in one block.
    TooManyAssignments = "too_many_assignments",
    // ---- dwell, subprograms and repeats of the CNC836 dialect (docs/language.md) ----
    /// G4 without its time F<seconds>.
    DwellWithoutTime = "dwell_without_time",
    /// G4 in a block with other words than N and F.
    DwellNotAlone = "dwell_not_alone",
    /// A subprogram form written wrong: `%L` without a number 1..9999, a call L or an end M17
    /// with other words, P without L, M17 written with a parameter.
    SubprogramSyntax = "subprogram_syntax",
    /// A subprogram number defined twice (`%L<n>`) in one program.
    SubprogramTwice = "subprogram_twice",
    /// A subprogram without its end M17 before the next `%L` or the end of the program.
    SubprogramWithoutReturn = "subprogram_without_return",
    /// M17 in the main program: no subprogram to end.
    ReturnWithoutCall = "return_without_call",
    // ---- feed and spindle (SPEC §5, §6) ----
    /// F out of its range (negative, above the per-minute or per-revolution maximum).
    FeedOutOfRange = "feed_out_of_range",
    /// A feed move with F = 0.
    FeedZero = "feed_zero",
    /// A feed move before any F.
    NoFeed = "no_feed",
    /// A feed move after the feed changed between per minute and per revolution, without F.
    FeedModeChanged = "feed_mode_changed",
    /// Feed per revolution without a turning spindle with a speed.
    FeedPerRevWithoutSpindle = "feed_per_rev_without_spindle",
    /// A feed per revolution above βmax = Vmax/S (warning).
    FeedAboveBetaMax = "feed_above_beta_max",
    /// G76 without S.
    G76NeedsS = "g76_needs_s",
    /// A negative S or spindle speed limit.
    NegativeSpeed = "negative_speed",
    /// A gear range (M41..M44) the machine does not have.
    GearNotConfigured = "gear_not_configured",
    // ---- arcs (SPEC §4.6) ----
    /// I, J or E in a block that is not an arc.
    ArcWordWithoutArc = "arc_word_without_arc",
    /// An arc without both centre words I and J.
    ArcNeedsCentre = "arc_needs_centre",
    /// An arc with zero radius.
    ArcRadiusZero = "arc_radius_zero",
    /// The arc end point misses the circle by more than R55.
    ArcEndOffCircle = "arc_end_off_circle",
    /// An arc replaced by a line (end point off the circle, 7.R397 = 1 or R397 d7; warning).
    ArcReplacedByLine = "arc_replaced_by_line",
    /// An E word that does not decode (SPEC §4.6).
    ERefinementInvalid = "e_refinement_invalid",
    /// The circle refinement R325 corrected a centre (information).
    ArcRefined = "arc_refined",
    /// An arc right after the length offset changed.
    ArcAfterOffsetChange = "arc_after_offset_change",
    /// A rotary axis moving in an arc.
    RotaryAxisInArc = "rotary_axis_in_arc",
    // ---- offsets and G92 (SPEC §3) ----
    /// G92 in a block with axis motion.
    G92WithMotion = "g92_with_motion",
    /// G92 without D, or with D0.
    G92NeedsEntry = "g92_needs_entry",
    /// G92 D<n> without any R0..R4 (warning).
    G92WritesNothing = "g92_writes_nothing",
    /// An offset entry outside 01..99.
    OffsetNoEntry = "offset_no_entry",
    /// An offset value outside ±99999.999 mm.
    OffsetValueOutOfRange = "offset_value_out_of_range",
    /// A TAB0.KOR line written wrong (text after `$KOR`, a second `$KOR`, not `NN: KEY=value`).
    OffsetFileSyntax = "offset_file_syntax",
    /// No `$KOR` line in a TAB0.KOR file.
    OffsetKorMissing = "offset_kor_missing",
    /// An entry listed twice in a TAB0.KOR file.
    OffsetEntryTwice = "offset_entry_twice",
    /// An entry number not written with two digits (`1:` for `01:`).
    OffsetEntryNotTwoDigits = "offset_entry_not_two_digits",
    /// A key that is not R, an axis name of this machine or an axis number 1..4.
    OffsetUnknownKey = "offset_unknown_key",
    /// A standard axis name used for another axis: the length is written by its number (SPEC §3).
    OffsetAxisByOrdinal = "offset_axis_by_ordinal",
    /// A key twice in one entry.
    OffsetKeyTwice = "offset_key_twice",
    /// An offset value that is missing, not a number, or has too many decimals.
    OffsetValueSyntax = "offset_value_syntax",
    // ---- radius compensation (SPEC §4) ----
    /// G41/G42 while 8.R95 = 0.
    CompDisabled = "comp_disabled",
    /// G41/G42 without a tool (D).
    CompWithoutTool = "comp_without_tool",
    /// Compensation started, changed or cancelled on an arc.
    CompChangeOnArc = "comp_change_on_arc",
    /// G41 directly after G42 or back (6.R397 = 0).
    CompSideSwitch = "comp_side_switch",
    /// G40 without motion in the compensation plane (7.R339 = 0).
    G40WithoutMotion = "g40_without_motion",
    /// The plane changed while compensation is active.
    PlaneChangeUnderComp = "plane_change_under_comp",
    /// An arc in another plane than the compensation plane.
    CompArcOtherPlane = "comp_arc_other_plane",
    /// Too many blocks without motion in the compensation plane.
    CompTooManyBridged = "comp_too_many_bridged",
    /// The tool radius is larger than an inside arc.
    ToolLargerThanArc = "tool_larger_than_arc",
    /// No intersection of equidistants (error; a warning when the arc is replaced, R397 d8).
    NoIntersection = "no_intersection",
    /// The equidistant runs backwards: the tool is too large for the detail (R397).
    EquidistantBackward = "equidistant_backward",
    /// The equidistant of an arc runs backwards; arc replaced by a line (R397 d5, warning).
    EquidistantArcBackward = "equidistant_arc_backward",
    /// An equidistant loop removed by the 3-block optimisation (R397 d3, information).
    LoopRemoved3Blocks = "loop_removed_3_blocks",
    /// An equidistant loop removed by the 4-block optimisation (R397 d4, information).
    LoopRemoved4Blocks = "loop_removed_4_blocks",
    /// On the exit from the contour the tool centre moves backwards (R764).
    ExitBackward = "exit_backward",
    /// The exit from the contour optimised, the backward move left out (R764, information).
    ExitOptimised = "exit_optimised",
    /// The equidistant lies far from the programmed corner (R765, warning).
    CornerFarFromEquidistant = "corner_far_from_equidistant",
    /// An arc of tool radius inserted at a corner (R339, information).
    CornerArcInserted = "corner_arc_inserted",
    /// The tool cuts into the contour (the gouge check).
    Gouge = "gouge",
    /// The gouge check stopped covering a long contour (information).
    GougeCheckLimited = "gouge_check_limited",
    // ---- the run ----
    /// A position beyond a soft limit (the diagnostic carries `limit`).
    SoftLimit = "soft_limit",
    /// A coordinate or radius that is not a finite number.
    NonFiniteCoordinate = "non_finite_coordinate",
    /// Lines after M2/M30 are not run (information).
    LinesAfterEnd = "lines_after_end",
    /// A jog while another jog, a program or a reference run moves the machine (issue #31:
    /// one motion source at a time).
    JogBusy = "jog_busy",
    /// A jog step that would end beyond a soft limit, or longer than any travel.
    JogBeyondTravel = "jog_beyond_travel",
    /// A command that moves the machine while its drives are being enabled (start-up, after
    /// Reset): UNAVAILABLE, try again once the machine is idle.
    MachineNotReady = "machine_not_ready",
    /// M6 in a block that moves or fills the table (G92): the tool changes at rest.
    ToolChangeNotAlone = "tool_change_not_alone",
    /// M6 while radius compensation is on.
    ToolChangeUnderComp = "tool_change_under_comp",
    /// Automatic tool changer: the tool of an M6 does not fit in the changer's tool number
    /// outputs (`[tool_change] tool_number_outputs`).
    ToolNumberBeyondOutputs = "tool_number_beyond_outputs",
    /// A touch-off while a program, MDI, a jog or a reference run moves or holds the machine.
    TouchOffBusy = "touch_off_busy",
    /// A touch-off before the axes are homed (the position it reads means nothing yet).
    TouchOffNotHomed = "touch_off_not_homed",
    /// A touch-off on an axis the offset table has no length for (axes 5 and 6), or a value
    /// the table cannot hold.
    TouchOffInvalid = "touch_off_invalid",
    /// A probing move or workflow while the machine is not idle (a program, a jog, a
    /// reference run, a fault).
    ProbeBusy = "probe_busy",
    /// A probing move or workflow before the axes are homed.
    ProbeNotHomed = "probe_not_homed",
    /// The machine has no probe input (`function = "probe"`, docs/io.md).
    ProbeUnavailable = "probe_unavailable",
    /// A probing move asked with an unknown axis, a distance or feed that is not usable.
    ProbeInvalid = "probe_invalid",
    /// The probing move ended without the probe changing (no contact within its travel).
    ProbeNoContact = "probe_no_contact",
    /// The probe was already in contact (or already clear, probing away) when the move started.
    ProbeAlreadyTriggered = "probe_already_triggered",
    /// The probing move was stopped (Stop, a fault, the e-stop) before it ended.
    ProbeAborted = "probe_aborted",
    /// A probing move in a program (G38.2..G38.5, CNC836 G31) under radius compensation.
    ProbeUnderComp = "probe_under_comp",
    /// A probing move in a program that cannot run: one that must find its change but ends
    /// where it starts, in inverse time (G93), or with a word it does not take.
    ProbeMoveInvalid = "probe_move_invalid",
    /// A restart whose scanned blocks pass a probing move (its result is not known).
    RestartPastProbe = "restart_past_probe",
    /// A restart from a block the program does not have (issue #31).
    RestartBlockNotFound = "restart_block_not_found",
    /// Too many errors: checking stopped.
    TooManyErrors = "too_many_errors",
    /// More messages than are listed (information).
    MessagesNotListed = "messages_not_listed",
    /// A defect of the controller, not of the program.
    Internal = "internal",
    // ---- machine setup and constants ----
    /// The machine's axis names cannot be used.
    AxisNamesInvalid = "axis_names_invalid",
    /// A constants line written wrong (not `Rnnn=value`).
    ConstantSyntax = "constant_syntax",
    /// A constant number that does not exist.
    ConstantUnknown = "constant_unknown",
    /// A constant set twice in one file.
    ConstantSetTwice = "constant_set_twice",
    /// A constant value that is not a number.
    ConstantNotANumber = "constant_not_a_number",
    /// A constant value with more than 5 digits before the point.
    ConstantTooManyDigits = "constant_too_many_digits",
    /// A constant value with more than 3 decimals.
    ConstantTooManyDecimals = "constant_too_many_decimals",
    /// A constant whose value has no meaning (validation).
    ConstantOutOfRange = "constant_out_of_range",
    // ---- files, API, preview ----
    /// A value given over the API outside its range.
    ValueOutOfRange = "value_out_of_range",
    /// A value given over the API with more decimals than the file keeps.
    ValueTooPrecise = "value_too_precise",
    /// A program file that cannot be read.
    ProgramUnreadable = "program_unreadable",
    /// Text (a program, a file sent over the API) that is not UTF-8.
    TextNotUtf8 = "text_not_utf8",
    /// A preview page that does not exist.
    PreviewNoSuchPage = "preview_no_such_page",
    /// A preview plane naming an axis the machine does not have.
    PreviewAxisMissing = "preview_axis_missing",
    /// The velocity plot stops at its bound of machining time; the program goes on.
    PreviewPlotCut = "preview_plot_cut",
    /// A program language (`dialect`) given over the API that cncd does not know.
    DialectUnknown = "dialect_unknown",
}

impl fmt::Display for DiagCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// One message about a program, a table file or a configuration, located for a machinist:
/// block number `N` when the block has one, and always the 1-based source line and column.
#[derive(Clone, Debug, PartialEq)]
pub struct Diagnostic {
    pub severity: Severity,
    /// What the message is about, stable for tests and HMIs.
    pub code: DiagCode,
    /// The `N` number of the block, if it was programmed.
    pub block: Option<u32>,
    /// 1-based line in the source text (0 when not tied to a line).
    pub line: u32,
    /// 1-based column in the line (0 when not tied to a column).
    pub column: u32,
    pub message: String,
    /// Set when the message is a soft-limit refusal (issue #15): which axis, where, which limit.
    pub limit: Option<crate::limits::LimitHit>,
    /// Set on the `messages_not_listed` note closing a capped list (issue #31): the messages
    /// found but not listed, by severity, so that [`DiagCounts::of`] gives the totals.
    pub not_listed: Option<DiagCounts>,
}

/// How many messages of each severity a pass found (listed or not).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DiagCounts {
    pub errors: u64,
    pub warnings: u64,
    pub infos: u64,
}

impl DiagCounts {
    pub fn add(&mut self, s: Severity) {
        match s {
            Severity::Error => self.errors += 1,
            Severity::Warning => self.warnings += 1,
            Severity::Info => self.infos += 1,
        }
    }

    /// The totals of a list capped by the pipeline: the listed messages plus what its
    /// `messages_not_listed` note counts (the note itself is not counted).
    pub fn of(list: &[Diagnostic]) -> DiagCounts {
        let mut c = DiagCounts::default();
        for d in list {
            match d.not_listed {
                Some(n) => {
                    c.errors += n.errors;
                    c.warnings += n.warnings;
                    c.infos += n.infos;
                }
                None => c.add(d.severity),
            }
        }
        c
    }

    pub fn total(&self) -> u64 {
        self.errors + self.warnings + self.infos
    }
}

impl Diagnostic {
    pub fn error(
        code: DiagCode,
        block: Option<u32>,
        line: u32,
        column: u32,
        message: impl Into<String>,
    ) -> Self {
        Diagnostic {
            severity: Severity::Error,
            code,
            block,
            line,
            column,
            message: message.into(),
            limit: None,
            not_listed: None,
        }
    }

    pub fn warning(
        code: DiagCode,
        block: Option<u32>,
        line: u32,
        column: u32,
        message: impl Into<String>,
    ) -> Self {
        Diagnostic {
            severity: Severity::Warning,
            ..Self::error(code, block, line, column, message)
        }
    }

    pub fn info(
        code: DiagCode,
        block: Option<u32>,
        line: u32,
        column: u32,
        message: impl Into<String>,
    ) -> Self {
        Diagnostic {
            severity: Severity::Info,
            ..Self::error(code, block, line, column, message)
        }
    }

    pub fn is_error(&self) -> bool {
        self.severity == Severity::Error
    }
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let sev = match self.severity {
            Severity::Info => "info",
            Severity::Warning => "warning",
            Severity::Error => "error",
        };
        write!(f, "{sev}")?;
        if let Some(n) = self.block {
            write!(f, " in block N{n}")?;
        }
        if self.line > 0 {
            write!(f, " (line {}, column {})", self.line, self.column)?;
        }
        write!(f, ": {}", self.message)
    }
}

#[cfg(test)]
mod tests {
    use super::DiagCode;

    #[test]
    fn codes_are_unique_snake_case_and_documented() {
        let doc = include_str!("../../docs/api.md");
        let mut seen = std::collections::HashSet::new();
        for c in DiagCode::ALL {
            let s = c.as_str();
            assert!(seen.insert(s), "{s} twice");
            assert!(
                s.bytes()
                    .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_'),
                "{s}"
            );
            assert!(doc.contains(&format!("`{s}`")), "{s} is not in docs/api.md");
        }
    }
}
