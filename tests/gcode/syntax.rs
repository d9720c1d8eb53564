//! Lexical syntax per dialect: block numbers, comments, `%`, block delete, case, numbers.

use kerf_tests::*;

fn o() -> Vec3 {
    v(0.0, 0.0, 0.0)
}

#[test]
fn empty_and_comment_only_programs_yield_nothing() {
    let cases = [
        (Dialect::LinuxCnc, "(only a comment)\n; and another\n\n"),
        (Dialect::Rockwell, "(ONLY A COMMENT) ;\n;\n"),
        (Dialect::Sinumerik, "; only a comment\n\n"),
        (Dialect::Heidenhain, "%EMPTY G71 *\nN99 %EMPTY G71 *\n"),
        (Dialect::Fagor, "; only a comment\n"),
    ];
    for (d, src) in cases {
        let its = items(d, src);
        assert!(its.is_empty(), "{}: {its:?}", d.name());
        let its = items(d, "");
        assert!(its.is_empty(), "{}: empty program gives {its:?}", d.name());
    }
}

#[test]
fn linuxcnc_percent_comments_block_delete_spaces_and_case() {
    // LinuxCNC G-code reference: a file may be delimited by `%` lines (anything after the
    // second `%` is ignored); `( )` and `;` comments; `/` block delete (guess: the block
    // delete switch is on here, so the block is skipped); spaces anywhere; case-insensitive.
    let ms = moves_with(
        Dialect::LinuxCnc,
        block_delete_on(),
        "%\n\
         (header comment)\n\
         N10 g21 g90 g17 (inline) g1 x1 y2 f100\n\
         n20 X3 ; trailing comment X99\n\
         /G1 X100\n\
         N30 G1 X 4 Y 5 . 5\n\
         G1 X.5 Y-.5 Z5.\n\
         %\n\
         G1 X1000 this is not G-code\n",
    );
    assert_eq!(ms.len(), 4, "{ms:#?}");
    assert_feed_line(&ms[0], o(), v(1.0, 2.0, 0.0), 100.0);
    assert_feed_line(&ms[1], v(1.0, 2.0, 0.0), v(3.0, 2.0, 0.0), 100.0);
    assert_feed_line(&ms[2], v(3.0, 2.0, 0.0), v(4.0, 5.5, 0.0), 100.0);
    assert_feed_line(&ms[3], v(4.0, 5.5, 0.0), v(0.5, -0.5, 5.0), 100.0);
    assert_eq!(
        [ms[0].line, ms[1].line, ms[2].line, ms[3].line],
        [3, 4, 6, 7]
    );
}

#[test]
fn rockwell_block_delete_and_lower_case() {
    let ms = moves_with(
        Dialect::Rockwell,
        block_delete_on(),
        "%\nn10 g01 x1 f100 ;\n/N20 G01 X100 ;\nN30 G01 Y2 ;\n",
    );
    assert_eq!(ms.len(), 2, "{ms:#?}");
    assert_feed_line(&ms[1], v(1.0, 0.0, 0.0), v(1.0, 2.0, 0.0), 100.0);
}

#[test]
fn sinumerik_block_delete_comments_and_lower_case() {
    let ms = moves_with(
        Dialect::Sinumerik,
        block_delete_on(),
        "n10 g1 x1 f100 ; comment with X99\n/N20 G1 X100\nN30 G1 Y2\n",
    );
    assert_eq!(ms.len(), 2, "{ms:#?}");
    assert_feed_line(&ms[0], o(), v(1.0, 0.0, 0.0), 100.0);
    assert_feed_line(&ms[1], v(1.0, 0.0, 0.0), v(1.0, 2.0, 0.0), 100.0);
}

#[test]
fn heidenhain_block_delete() {
    // Guess: TNC ISO hides `/` blocks like the other controls when block skip is active.
    let ms = moves_with(
        Dialect::Heidenhain,
        block_delete_on(),
        "%B G71 *\nN10 G01 X+1 F100 *\n/N20 G01 X+100 *\nN30 G01 Y+2 *\nN40 %B G71 *\n",
    );
    assert_eq!(ms.len(), 2, "{ms:#?}");
    assert_feed_line(&ms[1], v(1.0, 0.0, 0.0), v(1.0, 2.0, 0.0), 100.0);
}

#[test]
fn fagor_block_delete_and_lower_case() {
    let ms = moves_with(
        Dialect::Fagor,
        block_delete_on(),
        "n10 g01 x1 f100 ; comment\n/N20 G01 X100\nN30 G01 Y2\n",
    );
    assert_eq!(ms.len(), 2, "{ms:#?}");
    assert_feed_line(&ms[1], v(1.0, 0.0, 0.0), v(1.0, 2.0, 0.0), 100.0);
}

#[test]
fn numbers_with_signs_and_decimal_points() {
    for d in [Dialect::LinuxCnc, Dialect::Sinumerik, Dialect::Fagor] {
        let ms = moves(d, "G1 X+1.25 Y-0.75 Z-.5 F100\n");
        assert_feed_line(&ms[0], o(), v(1.25, -0.75, -0.5), 100.0);
    }
}

#[test]
fn sinumerik_transfer_header_lines_are_skipped() {
    // Siemens: `%` is the program start character used when writing programs on an
    // external PC (`%_N_NAME_MPF`), followed by a `;$PATH=` comment line.
    let ms = moves(
        Dialect::Sinumerik,
        "%_N_POCKET_MPF\n;$PATH=/_N_MPF_DIR\nN10 G1 X1 F100\nN20 M30\n",
    );
    assert_eq!(ms.len(), 1);
    assert_feed_line(&ms[0], o(), v(1.0, 0.0, 0.0), 100.0);
    assert_eq!(ms[0].line, 3);
}

#[test]
fn fagor_parenthesised_comments() {
    // [S] Fagor 8070 comments: `( )` as well as `;`.
    let ms = moves(
        Dialect::Fagor,
        "(ROUGHING) G01 X1 F100 (AT X1)\nG01 Y1 ; Y1\n",
    );
    assert_eq!(ms.len(), 2);
    assert_feed_line(&ms[1], v(1.0, 0.0, 0.0), v(1.0, 1.0, 0.0), 100.0);
}

#[test]
fn heidenhain_semicolon_comments() {
    // Guess (not confirmed by the seed): TNC ISO comments start with `;` and run to the end
    // of the block.
    let ms = moves(
        Dialect::Heidenhain,
        "%C G71 *\nN10 ; roughing X+99 *\nN20 G01 X+1 F100 *\nN30 %C G71 *\n",
    );
    assert_eq!(ms.len(), 1, "{ms:#?}");
    assert_feed_line(&ms[0], o(), v(1.0, 0.0, 0.0), 100.0);
}

#[test]
fn rockwell_several_blocks_per_line_keep_their_own_modal_words() {
    // `;` ends a block: the second block on the line is a block of its own, so its modal
    // words (G91 here) take effect after the first block's move.
    let ms = moves(Dialect::Rockwell, "G01 X10 F100 ; G91 X5 ; X5 ;\n");
    assert_eq!(ms.len(), 3);
    assert_feed_line(&ms[1], v(10.0, 0.0, 0.0), v(15.0, 0.0, 0.0), 100.0);
    assert_feed_line(&ms[2], v(15.0, 0.0, 0.0), v(20.0, 0.0, 0.0), 100.0);
}

#[test]
fn linuxcnc_semicolon_inside_a_parenthesised_comment_is_text() {
    let ms = moves(Dialect::LinuxCnc, "(a; b) G1 X1 F100\n");
    assert_feed_line(&ms[0], o(), v(1.0, 0.0, 0.0), 100.0);
}

#[test]
fn word_order_inside_a_block_does_not_matter() {
    // RS274/NGC: the words of a block may be written in any order.
    let a = moves(Dialect::LinuxCnc, "X1 Y2 F100 G1\nJ0 I-1 X0 Y1 G3\n");
    let b = moves(Dialect::LinuxCnc, "G1 X1 Y2 F100\nG3 X0 Y1 I-1 J0\n");
    assert_same_moves("word order", &a, &b, 0.0);
}

/// Settings with the block delete switch on (it is off by default).
fn block_delete_on() -> Settings {
    Settings {
        block_delete: true,
        ..Default::default()
    }
}

#[test]
fn block_delete_off_by_default_runs_the_block_in_every_dialect() {
    for (d, src, n) in [
        (Dialect::LinuxCnc, "G1 X1 F100\n/G1 X100\nG1 Y2\n", 3),
        (
            Dialect::Rockwell,
            "N10 G01 X1 F100 ;\n/N20 G01 X100 ;\nN30 G01 Y2 ;\n",
            3,
        ),
        (
            Dialect::Sinumerik,
            "N10 G1 X1 F100\n/N20 G1 X100\nN30 G1 Y2\n",
            3,
        ),
        (
            Dialect::Fagor,
            "N10 G01 X1 F100\n/N20 G01 X100\nN30 G01 Y2\n",
            3,
        ),
    ] {
        let off = moves(d, src);
        assert_eq!(off.len(), n, "{}", d.name());
        assert_feed_line(&off[1], v(1.0, 0.0, 0.0), v(100.0, 0.0, 0.0), 100.0);
        let on = moves_with(d, block_delete_on(), src);
        assert_eq!(on.len(), n - 1, "{}", d.name());
        assert_feed_line(&on[1], v(1.0, 0.0, 0.0), v(1.0, 2.0, 0.0), 100.0);
    }
    // LinuxCNC: a deleted line of the language layer (a parameter set) runs too when off.
    let ms = moves(Dialect::LinuxCnc, "#1=5\n/#1=7\nG1 X#1 F100\n");
    assert_feed_line(&ms[0], o(), v(7.0, 0.0, 0.0), 100.0);
    let ms = moves_with(
        Dialect::LinuxCnc,
        block_delete_on(),
        "#1=5\n/#1=7\nG1 X#1 F100\n",
    );
    assert_feed_line(&ms[0], o(), v(5.0, 0.0, 0.0), 100.0);
}
