// Penelope FPGA kinematics: forward kinematics of a 6-joint DH chain and the force
// transformation tau = J^T [f; m], for a Virtex-II XC2V1000 at 40 MHz.
//
// Bit-exact with the Rust model penelope_fpga::pipeline (fpga/src/pipeline.rs); every node's
// format, rounding and overflow is in fpga/SPEC.md; the cycle schedule is
// penelope_fpga::cycles (FK 61 cycles, FK + force 92 cycles).
//
// Interface: put the inputs on the ports and raise `start` for one cycle while `busy` is low;
// the inputs and the DH table are latched on that edge. `done` pulses high for one cycle on the
// edge that completes; the outputs then hold until the next result. A new `start` is accepted
// on the edge right after `done`.
//
// Datapath: the state machine decides each cycle which operation issues and registers that
// decision (operand source codes and datapath actions), so the datapath runs one edge behind
// it; the registered codes select the operands of three shared 25 x 25 signed multipliers
// (four MULT18X18 each), then a three-stage pipeline:
//   M  products registered (pr0..pr2)                        edge t
//   A  exact sum: addend + pr0 +- pr1 + pr2 registered (acc) edge t + 1
//   Q  quantized (truncate / round, wrap / saturate) into its destination register, edge t + 2
// One operation issues per cycle; the schedule (below and in penelope_fpga::cycles) is ordered
// so that no operation reads a register before the Q stage has written it, without stalls
// except one bubble before the last torque. The sine/cosine unit (kin_sincos: block-RAM table,
// three pipeline stages) works one joint ahead.
//
// Schedule, edges counted from the one that samples `start` (e0); e1 registers the first
// decision, so every datapath event below is one edge after the state machine's cycle:
//   e2, e3      the table ROM reads joint 0's angle; the interpolation products
//   e4          sine and cosine of joint 0 loaded
//   joint j, issue k = 0..8 at edge e(5 + 9j + k):
//     k 0..5    n0_0..2, n1_0..2 (c R_i0 + s R_i1, c R_i1 - s R_i0)
//     k 6..8    p_0..2 (p_i + a n0_i + d R_i2); on k = 8 R is committed
//     k 0 / 2   z_j / o_j saved; k 6: the ROM reads joint j+1's angle; k 8: it is loaded
//   FK done     two edges after the last issue: e60, 61 cycles
//   force       6 issues f0_i, m0_i; then mj of joint 0, mj of joint 1, tau_0, mj of joint 2,
//               tau_1, ... mj of joint 5, tau_4, one bubble, tau_5: 31 issues; done two edges
//               after the last: 92 cycles
//
// Per-joint data (angles, DH rows, saved frames z_j and o_j, moments, torques) live in shift
// registers, so no multiplexer is indexed by the joint number.
//
// Planted bugs for the co-simulation's mutation check (never defined in a real build):
//   MUTANT_LOGICAL_SHIFT  `>>` for `>>>` in the saturating wrench nodes
//   MUTANT_HALF_UP        round-half-up instead of half-even in the lever node
//   MUTANT_DROP_LSB       position sums lose their least significant result bit
//   (kin_sincos.v)        MUTANT_SINCOS_TRUNC
//   MUTANT_LINT_WIDTH     a width mismatch that verilator -Wall must report (tests/lint.rs)
`timescale 1ns/1ps
module penelope_kin (
    input  wire         clk,
    input  wire         rst,            // synchronous, active high
    input  wire         start,
    input  wire         force_op,       // 1: forward kinematics, then the force path
    input  wire         flange_frame,   // 1: wrench in the flange frame (rotated to the base)
    input  wire [143:0] q,              // 6 x <+-,24,1> pi-rad, joint j at [24j +: 24]
    input  wire [149:0] wrench,         // [fx fy fz mx my mz] x <+-,25,8>, at [25k +: 25]
    input  wire [143:0] dh_offset,      // 6 x <+-,24,1> pi-rad
    input  wire [149:0] dh_a,           // 6 x <+-,25,1> m
    input  wire [149:0] dh_d,           // 6 x <+-,25,1> m
    input  wire [11:0]  dh_alpha,       // 6 x 2-bit code: 0, +90, 180, -90 degrees
    output wire         busy,
    output reg          done,
    output wire [224:0] rot,            // R[i][k] <+-,25,2> at [25(3i+k) +: 25]
    output wire [95:0]  pos,            // p[i] <+-,32,2> m at [32i +: 32]
    output wire [149:0] base_wrench,    // [f0; m0] <+-,25,8> at [25k +: 25]
    output wire [149:0] tau             // tau[j] <+-,25,8> N m at [25j +: 25]
);
    // Issue states.
    localparam [2:0] S_IDLE = 3'd0, S_PRE = 3'd1, S_FK = 3'd2, S_WROT = 3'd3, S_MX = 3'd4,
                     S_TAU = 3'd5, S_BUB = 3'd6, S_WAIT = 3'd7;
    // Operations travelling down the pipeline.
    localparam [2:0] OP_NONE = 3'd0, OP_ROT = 3'd1, OP_POS = 3'd2, OP_WROT = 3'd3,
                     OP_MX = 3'd4, OP_TAU = 3'd5;

    reg [2:0] state, j;
    reg [3:0] k;
    reg       op_force, flange, last_tau;

    // Per-joint shift registers: the current joint's entry is always at the bottom.
    reg [143:0] qs, offs;
    reg [149:0] as, ds;
    reg [11:0]  alphas;
    reg [449:0] zs;                     // z_j (3 x 25): appended on top, rotated in the force path
    reg [575:0] os;                     // o_j (3 x 32)
    reg [99:0]  mjs;                    // the last four moment components, newest on top
    reg [149:0] taus;                   // tau_j, shifted in on top

    reg signed [24:0] w0, w1, w2, w3, w4, w5;                      // latched wrench
    reg signed [24:0] r00, r01, r02, r10, r11, r12, r20, r21, r22; // R
    reg signed [31:0] p0, p1, p2;                                  // p
    reg signed [24:0] n00, n01, n02, n10, n11, n12;                // R Rz(theta) columns 0, 1
    reg signed [24:0] f0x, f0y, f0z, m0x, m0y, m0z;                // base-frame wrench
    reg signed [24:0] L0, L1, L2;                                  // lever arm p - o_j

    // The registered issue decision (see "issue decode" below): operand codes, the operation,
    // and the datapath actions, all one edge behind the state machine.
    reg [3:0] u_a0, u_a1, u_a2, u_b0, u_b1, u_b2;
    reg [2:0] u_op, u_idx;
    reg       u_last, u_last_tau;
    reg       u_zs, u_os, u_qshift, u_scload, u_commit, u_lever, u_zrot;

    assign busy = (state != S_IDLE);
    assign rot = {r22, r21, r20, r12, r11, r10, r02, r01, r00};
    assign pos = {p2, p1, p0};
    assign base_wrench = {m0z, m0y, m0x, f0z, f0y, f0x};
    assign tau = taus;

    // --- the sine/cosine unit: theta = q_j + offset_j, wrapped to 24 bits ---------------------
    // The ROM stage samples the bottom angle on every edge; `u_scload` moves the result of the
    // angle sampled two edges before into S and C.
    wire [23:0] theta = qs[23:0] + offs[23:0];
    wire signed [24:0] S, C;
    kin_sincos u_sincos (.clk(clk), .angle(theta), .load(u_scload), .sin_o(S), .cos_o(C));

    wire signed [24:0] a_j = as[24:0];
    wire signed [24:0] d_j = ds[24:0];
    wire [1:0] alpha_j = alphas[1:0];

    // --- lever arms r = p - o_j: round half-even over 7 fraction bits, wrap to 25 bits --------
    function signed [24:0] lever7(input signed [31:0] p, input signed [31:0] o);
        reg signed [32:0] diff, t;
        begin
            diff = {p[31], p} - {o[31], o};
            t = diff >>> 7;
`ifdef MUTANT_HALF_UP
            if (diff[6])
`else
            if (diff[6] && ((|diff[5:0]) || t[0]))
`endif
                t = t + 33'sd1;
            lever7 = t[24:0];
        end
    endfunction

    // --- issue decode (control timeline) --------------------------------------------------------
    // The state machine decides, one cycle ahead, which operation issues and where its operands
    // come from; that decision is registered (u_*), and the datapath acts on the registered
    // decision. So the operand multiplexers are selected straight from flip-flops (no state
    // decoding in front of the multipliers), and every datapath action happens one edge after
    // the state machine's cycle that decided it.
    //
    // Operand source codes:
    //   ma0: 0 zero, 1 C, 2 a_j, 3 r00, 4 r10, 5 r20, 6 L0, 7 L1, 8 L2, 9 z_j.x
    //   ma1: 0 zero, 1 S, 2 d_j, 3 r01, 4 r11, 5 r21, 6 L0, 7 L1, 8 L2, 9 z_j.y
    //   ma2: 0 zero,             3 r02, 4 r12, 5 r22,                  9 z_j.z
    //   mb0: 0 zero, 1 r00, 2 r10, 3 r20, 4 r01, 5 r11, 6 r21, 7 n00, 8 n01, 9 n02,
    //        10 w0, 11 w3, 12 f0x, 13 f0y, 14 f0z, 15 mj.x
    //   mb1: 0 zero, 1 r00, 2 r10, 3 r20, 4 r01, 5 r11, 6 r21, 7 r02, 8 r12, 9 r22,
    //        10 w1, 11 w4, 12 f0x, 13 f0y, 14 f0z, 15 mj.y
    //   mb2: 0 zero, 10 w2, 11 w5, 15 mj.z
    reg [3:0] ca0, ca1, ca2, cb0, cb1, cb2;
    reg [2:0] iop;                      // the operation decided this cycle
    reg [2:0] iidx;                     // its destination index
    reg       ilast;                    // its result completes the request
    wire [3:0] row = (k == 4'd1 || k == 4'd4) ? 4'd4 : (k == 4'd2 || k == 4'd5) ? 4'd5 : 4'd3;

    always @* begin
        ca0 = 4'd0; ca1 = 4'd0; ca2 = 4'd0; cb0 = 4'd0; cb1 = 4'd0; cb2 = 4'd0;
        iop = OP_NONE;
        iidx = k[2:0];
        ilast = 1'b0;
        case (state)
            S_FK: begin
                if (k < 4'd6) begin
                    // n0_i = c R_i0 + s R_i1 (k = i); n1_i = c R_i1 - s R_i0 (k = 3 + i)
                    iop = OP_ROT;
                    ca0 = 4'd1; ca1 = 4'd1;
                    case (k)
                        4'd0:    begin cb0 = 4'd1; cb1 = 4'd4; end
                        4'd1:    begin cb0 = 4'd2; cb1 = 4'd5; end
                        4'd2:    begin cb0 = 4'd3; cb1 = 4'd6; end
                        4'd3:    begin cb0 = 4'd4; cb1 = 4'd1; end
                        4'd4:    begin cb0 = 4'd5; cb1 = 4'd2; end
                        default: begin cb0 = 4'd6; cb1 = 4'd3; end
                    endcase
                end else begin
                    // p_i + a n0_i + d R_i2 (k = 6 + i)
                    iop = OP_POS;
                    ca0 = 4'd2; ca1 = 4'd2;
                    case (k)
                        4'd6:    begin cb0 = 4'd7; cb1 = 4'd7; iidx = 3'd0; end
                        4'd7:    begin cb0 = 4'd8; cb1 = 4'd8; iidx = 3'd1; end
                        default: begin cb0 = 4'd9; cb1 = 4'd9; iidx = 3'd2; end
                    endcase
                    ilast = (k == 4'd8) && (j == 3'd5) && !op_force;
                end
            end
            S_WROT: begin   // R_i . f (k = i), R_i . m (k = 3 + i)
                iop = OP_WROT;
                ca0 = row; ca1 = row; ca2 = row;
                if (k < 4'd3) begin
                    cb0 = 4'd10; cb1 = 4'd10; cb2 = 4'd10;
                end else begin
                    cb0 = 4'd11; cb1 = 4'd11; cb2 = 4'd11;
                end
            end
            S_MX: begin     // m0_k + (r x f0)_k
                iop = OP_MX;
                case (k)
                    4'd0:    begin ca0 = 4'd7; cb0 = 4'd14; ca1 = 4'd8; cb1 = 4'd13; end
                    4'd1:    begin ca0 = 4'd8; cb0 = 4'd12; ca1 = 4'd6; cb1 = 4'd14; end
                    default: begin ca0 = 4'd6; cb0 = 4'd13; ca1 = 4'd7; cb1 = 4'd12; end
                endcase
            end
            S_TAU: begin    // z_j . mj
                iop = OP_TAU;
                ca0 = 4'd9; ca1 = 4'd9; ca2 = 4'd9;
                cb0 = 4'd15; cb1 = 4'd15; cb2 = 4'd15;
                ilast = last_tau;
            end
            default: ;
        endcase
    end


    // --- operand multiplexers, selected by registered codes ----------------------------------
    // tau_j (j < 5) reads the three moments below the newest (the newest is already joint
    // j+1's mj_x); tau_5, after its bubble, reads the newest three.
    wire signed [24:0] mjx = u_last_tau ? mjs[49:25] : mjs[24:0];
    wire signed [24:0] mjy = u_last_tau ? mjs[74:50] : mjs[49:25];
    wire signed [24:0] mjz = u_last_tau ? mjs[99:75] : mjs[74:50];

    function signed [24:0] pick_a(input [3:0] code, input signed [24:0] s1, input signed [24:0] s2,
                                  input signed [24:0] s3, input signed [24:0] s4,
                                  input signed [24:0] s5, input signed [24:0] s9);
        begin
            case (code)
                4'd1:    pick_a = s1;
                4'd2:    pick_a = s2;
                4'd3:    pick_a = s3;
                4'd4:    pick_a = s4;
                4'd5:    pick_a = s5;
                4'd6:    pick_a = L0;
                4'd7:    pick_a = L1;
                4'd8:    pick_a = L2;
                4'd9:    pick_a = s9;
                default: pick_a = 25'sd0;
            endcase
        end
    endfunction

    function signed [24:0] pick_b(input [3:0] code, input signed [24:0] s7,
                                  input signed [24:0] s8, input signed [24:0] s9,
                                  input signed [24:0] s10, input signed [24:0] s11,
                                  input signed [24:0] s15);
        begin
            case (code)
                4'd1:    pick_b = r00;
                4'd2:    pick_b = r10;
                4'd3:    pick_b = r20;
                4'd4:    pick_b = r01;
                4'd5:    pick_b = r11;
                4'd6:    pick_b = r21;
                4'd7:    pick_b = s7;
                4'd8:    pick_b = s8;
                4'd9:    pick_b = s9;
                4'd10:   pick_b = s10;
                4'd11:   pick_b = s11;
                4'd12:   pick_b = f0x;
                4'd13:   pick_b = f0y;
                4'd14:   pick_b = f0z;
                4'd15:   pick_b = s15;
                default: pick_b = 25'sd0;
            endcase
        end
    endfunction

    wire signed [24:0] ma0 = pick_a(u_a0, C, a_j, r00, r10, r20, zs[24:0]);
    wire signed [24:0] ma1 = pick_a(u_a1, S, d_j, r01, r11, r21, zs[49:25]);
    wire signed [24:0] ma2 = pick_a(u_a2, 25'sd0, 25'sd0, r02, r12, r22, zs[74:50]);
    wire signed [24:0] mb0 = pick_b(u_b0, n00, n01, n02, w0, w3, mjx);
    wire signed [24:0] mb1 = pick_b(u_b1, r02, r12, r22, w1, w4, mjy);
    wire signed [24:0] mb2 = pick_b(u_b2, 25'sd0, 25'sd0, 25'sd0, w2, w5, mjz);

    // --- pipeline registers -------------------------------------------------------------------
    reg signed [49:0] pr0, pr1, pr2;    // M: exact 25 x 25 products
    reg [2:0] m_op, m_idx, a_op, a_idx;
    reg       m_last, a_last;
    reg signed [51:0] acc;              // A: exact sum, |acc| < 2^50

    // A stage: the addend (position or moment, aligned to the products' LSB) and the sign of
    // the second product.
    reg signed [51:0] addend;
    reg               sub1;
    always @* begin
        addend = 52'sd0;
        sub1 = 1'b0;
        case (m_op)
            OP_ROT: sub1 = (m_idx >= 3'd3);
            OP_POS: case (m_idx)
                3'd0:    addend = {{3{p0[31]}}, p0, 17'd0};
                3'd1:    addend = {{3{p1[31]}}, p1, 17'd0};
                default: addend = {{3{p2[31]}}, p2, 17'd0};
            endcase
            OP_MX: begin
                sub1 = 1'b1;
                case (m_idx)
                    3'd0:    addend = {{4{m0x[24]}}, m0x, 23'd0};
                    3'd1:    addend = {{4{m0y[24]}}, m0y, 23'd0};
                    default: addend = {{4{m0z[24]}}, m0z, 23'd0};
                endcase
            end
            default: ;
        endcase
    end
    wire signed [51:0] x0 = {{2{pr0[49]}}, pr0};
    wire signed [51:0] x1 = {{2{pr1[49]}}, pr1};
    wire signed [51:0] x2 = {{2{pr2[49]}}, pr2};

    // --- Q stage: quantizers ----------------------------------------------------------------
    // Truncate (floor) 23 fraction bits, then saturate to 25 bits.
    function signed [24:0] trunc_sat23(input signed [51:0] a);
        reg signed [51:0] t;
        begin
`ifdef MUTANT_LOGICAL_SHIFT
            t = a >> 23;
`else
            t = a >>> 23;
`endif
            if (t[51:24] == {28{t[51]}})
                trunc_sat23 = t[24:0];
            else
                trunc_sat23 = t[51] ? 25'h1000000 : 25'h0FFFFFF;
        end
    endfunction

    // Round half-even over 23 fraction bits, then saturate to 25 bits (|a| < 2^50, so t + 1
    // cannot overflow).
    function signed [24:0] rhe_sat23(input signed [51:0] a);
        reg signed [28:0] t;
        begin
            t = a[51:23];
            if (a[22] && ((|a[21:0]) || t[0]))
                t = t + 29'sd1;
            if (t[28:24] == {5{t[28]}})
                rhe_sat23 = t[24:0];
            else
                rhe_sat23 = t[28] ? 25'h1000000 : 25'h0FFFFFF;
        end
    endfunction

    wire signed [24:0] q_rot = acc[47:23];            // truncate 46 -> 23, wrap to 25 bits
`ifdef MUTANT_DROP_LSB
    wire signed [31:0] q_pos = {acc[48:18], 1'b0};
`else
    wire signed [31:0] q_pos = acc[48:17];            // truncate 47 -> 30, wrap to 32 bits
`endif
    wire signed [24:0] q_sat = trunc_sat23(acc);
    wire signed [24:0] q_rhe = rhe_sat23(acc);

    // The low 17 bits of a position sum and the top bits of acc beyond the formats are
    // dropped by the quantizers on purpose (truncation and wrap).
    wire _unused = &{1'b0, acc[16:0]};
`ifdef MUTANT_LINT_WIDTH
    wire [3:0] lint_mutant_unused = j;   // planted for tests/lint.rs: 3 bits into 4 (WIDTH)
`endif

    // --- the clocked process -------------------------------------------------------------------
    always @(posedge clk) begin
        done <= 1'b0;

        // M, A: products and sums of whatever was issued (OP_NONE results are ignored).
        pr0 <= ma0 * mb0;
        pr1 <= ma1 * mb1;
        pr2 <= ma2 * mb2;
        acc <= addend + x0 + (sub1 ? -x1 : x1) + x2;
        m_idx <= u_idx;
        a_idx <= m_idx;
        m_last <= u_last;
        a_last <= m_last;

        // Q: write the result.
        case (a_op)
            OP_ROT: case (a_idx)
                3'd0:    n00 <= q_rot;
                3'd1:    n01 <= q_rot;
                3'd2:    n02 <= q_rot;
                3'd3:    n10 <= q_rot;
                3'd4:    n11 <= q_rot;
                default: n12 <= q_rot;
            endcase
            OP_POS: case (a_idx)
                3'd0:    p0 <= q_pos;
                3'd1:    p1 <= q_pos;
                default: p2 <= q_pos;
            endcase
            OP_WROT: case (a_idx)
                3'd0:    f0x <= flange ? q_sat : w0;
                3'd1:    f0y <= flange ? q_sat : w1;
                3'd2:    f0z <= flange ? q_sat : w2;
                3'd3:    m0x <= flange ? q_sat : w3;
                3'd4:    m0y <= flange ? q_sat : w4;
                default: m0z <= flange ? q_sat : w5;
            endcase
            OP_MX:  mjs <= {q_sat, mjs[99:25]};
            OP_TAU: taus <= {q_rhe, taus[149:25]};
            default: ;
        endcase

        // The registered decision.
        u_a0 <= ca0; u_a1 <= ca1; u_a2 <= ca2; u_b0 <= cb0; u_b1 <= cb1; u_b2 <= cb2;
        u_idx <= iidx;
        u_last <= ilast;
        u_last_tau <= last_tau;

        // Datapath actions decided on the previous cycle.
        if (u_zs)
            zs <= {r22, r12, r02, zs[449:75]};
        if (u_zrot)
            zs <= {zs[74:0], zs[449:75]};     // the next joint's z_j to the bottom
        if (u_os)                             // the previous joint's p2 was written before
            os <= {p2, p1, p0, os[575:96]};
        if (u_lever) begin                    // this (first) or the next joint's lever arm
            L0 <= lever7(p0, os[31:0]);
            L1 <= lever7(p1, os[63:32]);
            L2 <= lever7(p2, os[95:64]);
            os <= {os[95:0], os[575:96]};
        end
        if (u_qshift) begin
            qs <= qs >> 24; offs <= offs >> 24;
        end
        if (u_commit) begin
            // Commit R <- [n0, alpha(n1, R_2)].
            r00 <= n00; r10 <= n01; r20 <= n02;
            case (alpha_j)
                2'd0: begin
                    r01 <= n10;  r11 <= n11;  r21 <= n12;
                end
                2'd1: begin
                    r01 <= r02;  r11 <= r12;  r21 <= r22;
                    r02 <= -n10; r12 <= -n11; r22 <= -n12;
                end
                2'd2: begin
                    r01 <= -n10; r11 <= -n11; r21 <= -n12;
                    r02 <= -r02; r12 <= -r12; r22 <= -r22;
                end
                default: begin
                    r01 <= -r02; r11 <= -r12; r21 <= -r22;
                    r02 <= n10;  r12 <= n11;  r22 <= n12;
                end
            endcase
            as <= as >> 25; ds <= ds >> 25; alphas <= alphas >> 2;
        end

        // The state machine (control timeline).
        if (rst) begin
            state <= S_IDLE;
            j <= 3'd0;
            k <= 4'd0;
            u_op <= OP_NONE;
            m_op <= OP_NONE;
            a_op <= OP_NONE;
            {u_zs, u_os, u_qshift, u_scload, u_commit, u_lever, u_zrot} <= 7'd0;
        end else begin
            u_op <= iop;
            m_op <= u_op;
            a_op <= m_op;
            u_zs <= (state == S_FK) && (k == 4'd0);
            u_os <= (state == S_FK) && (k == 4'd2);
            u_qshift <= ((state == S_PRE) && (k == 4'd0)) || ((state == S_FK) && (k == 4'd6));
            u_scload <= ((state == S_PRE) && (k == 4'd2)) || ((state == S_FK) && (k == 4'd8));
            u_commit <= (state == S_FK) && (k == 4'd8);
            u_lever <= ((state == S_WROT) && (k == 4'd5)) || ((state == S_MX) && (k == 4'd2));
            u_zrot <= (state == S_TAU);
            if (a_op != OP_NONE && a_last) begin
                state <= S_IDLE;
                done <= 1'b1;
            end
            case (state)
                S_IDLE: if (start) begin
                    qs <= q; offs <= dh_offset; as <= dh_a; ds <= dh_d; alphas <= dh_alpha;
                    w0 <= wrench[24:0];    w1 <= wrench[49:25];   w2 <= wrench[74:50];
                    w3 <= wrench[99:75];   w4 <= wrench[124:100]; w5 <= wrench[149:125];
                    op_force <= force_op;
                    flange <= flange_frame;
                    r00 <= 25'sh0800000; r01 <= 25'sd0; r02 <= 25'sd0;         // R = I
                    r10 <= 25'sd0; r11 <= 25'sh0800000; r12 <= 25'sd0;
                    r20 <= 25'sd0; r21 <= 25'sd0; r22 <= 25'sh0800000;
                    p0 <= 32'sd0; p1 <= 32'sd0; p2 <= 32'sd0;
                    j <= 3'd0;
                    k <= 4'd0;
                    state <= S_PRE;
                end
                S_PRE: begin   // k 0: joint 0's angle to the ROM; k 2: S, C loaded
                    if (k != 4'd2)
                        k <= k + 4'd1;
                    else begin
                        k <= 4'd0;
                        state <= S_FK;
                    end
                end
                S_FK: begin
                    if (k == 4'd8) begin
                        k <= 4'd0;
                        if (j == 3'd5) begin
                            j <= 3'd0;
                            state <= op_force ? S_WROT : S_WAIT;
                        end else
                            j <= j + 3'd1;
                    end else
                        k <= k + 4'd1;
                end
                S_WROT: begin
                    if (k == 4'd5) begin
                        k <= 4'd0;
                        j <= 3'd0;
                        state <= S_MX;
                    end else
                        k <= k + 4'd1;
                end
                S_MX: begin    // moments of joint j
                    if (k == 4'd2) begin
                        k <= 4'd0;
                        last_tau <= 1'b0;
                        state <= (j == 3'd0) ? S_MX : S_TAU;   // tau_(j-1) follows mj of j
                        if (j == 3'd0)
                            j <= 3'd1;
                    end else
                        k <= k + 4'd1;
                end
                S_TAU: begin
                    if (last_tau)
                        state <= S_WAIT;
                    else if (j == 3'd5)
                        state <= S_BUB;               // tau_5 waits for mj of joint 5
                    else begin
                        j <= j + 3'd1;
                        state <= S_MX;
                    end
                end
                S_BUB: begin
                    last_tau <= 1'b1;
                    state <= S_TAU;
                end
                default: ;   // S_WAIT: the Q stage ends the request
            endcase
        end
    end
endmodule
