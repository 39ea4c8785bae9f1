// Penelope FPGA kinematics: forward kinematics of a 6-joint DH chain and the force
// transformation tau = J^T [f; m], one finite-state machine with three shared 25x25 signed
// multipliers and one sine/cosine unit (kin_sincos).
//
// Bit-exact with the Rust model penelope_fpga::pipeline (fpga/src/pipeline.rs); every node's
// format, rounding and overflow is in fpga/SPEC.md; the cycle schedule is
// penelope_fpga::cycles (FK 61 cycles, FK + force 91 cycles, at 40 MHz).
//
// Interface: put the inputs on the ports and raise `start` for one cycle while `busy` is low;
// the inputs and the DH table are latched on that edge. `done` pulses high for one cycle on the
// edge that completes; the outputs then hold until the next result. A new `start` is accepted
// on the edge right after `done`.
//
// Per-joint data (angles, DH rows, saved frames z_j and o_j, torques) live in shift registers
// that advance once per joint, so no multiplexer is indexed by the joint number.
//
// Planted bugs for the co-simulation's mutation check (never defined in a real build):
//   MUTANT_LOGICAL_SHIFT  `>>` for `>>>` in the saturating wrench nodes
//   MUTANT_HALF_UP        round-half-up instead of half-even in the lever node
//   MUTANT_DROP_LSB       position sums lose their least significant result bit
//   (kin_sincos.v)        MUTANT_SINCOS_TRUNC
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
    localparam S_IDLE = 3'd0, S_ANG = 3'd1, S_ROT = 3'd2, S_POS = 3'd3,
               S_WROT = 3'd4, S_MX = 3'd5, S_TAU = 3'd6;

    reg [2:0] state, k, j;
    reg       op_force, flange;

    // Per-joint shift registers: the current joint's entry is always at the bottom.
    reg [143:0] qs, offs;
    reg [149:0] as, ds;
    reg [11:0]  alphas;
    reg [449:0] zs;                     // z_j (3 x 25): appended on top, rotated in the force path
    reg [575:0] os;                     // o_j (3 x 32)
    reg [149:0] taus;                   // tau_j, shifted in on top

    reg signed [24:0] w0, w1, w2, w3, w4, w5;                      // latched wrench
    reg signed [24:0] r00, r01, r02, r10, r11, r12, r20, r21, r22; // R
    reg signed [31:0] p0, p1, p2;                                  // p
    reg signed [24:0] n00, n01, n02, n10, n11, n12;                // R Rz(theta) columns 0, 1
    reg signed [24:0] S, C;
    reg signed [24:0] f0x, f0y, f0z, m0x, m0y, m0z;                // base-frame wrench
    reg signed [24:0] mj0, mj1, mj2;                               // moment about o_j

    assign busy = (state != S_IDLE);
    assign rot = {r22, r21, r20, r12, r11, r10, r02, r01, r00};
    assign pos = {p2, p1, p0};
    assign base_wrench = {m0z, m0y, m0x, f0z, f0y, f0x};
    assign tau = taus;

    // --- the sine/cosine unit: theta = q_j + offset_j, wrapped to 24 bits ---------------------
    wire [23:0] theta = qs[23:0] + offs[23:0];
    wire signed [24:0] sin_w, cos_w;
    kin_sincos u_sincos (.angle(theta), .sin_o(sin_w), .cos_o(cos_w));

    wire signed [24:0] a_j = as[24:0];
    wire signed [24:0] d_j = ds[24:0];
    wire [1:0] alpha_j = alphas[1:0];

    // --- lever arms r = p - o_j: round half-even over 7 fraction bits, wrap to 25 bits --------
    // (computed on the edge before each joint's S_MX cycles: a subtractor per axis)
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

    reg signed [24:0] L0, L1, L2;       // registered once per joint of the force path

    // --- saturation helpers ---------------------------------------------------------------------
    // Saturate a value already on the output grid into 25 bits.
    function signed [24:0] sat25(input signed [63:0] t);
        begin
            if (t > 64'sd16777215)
                sat25 = 25'h0FFFFFF;
            else if (t < -64'sd16777216)
                sat25 = 25'h1000000;
            else
                sat25 = t[24:0];
        end
    endfunction

    // Truncate (floor) 23 fraction bits, then saturate to 25 bits.
    function signed [24:0] trunc_sat23(input signed [63:0] acc);
        reg signed [63:0] t;
        begin
`ifdef MUTANT_LOGICAL_SHIFT
            t = acc >> 23;
`else
            t = acc >>> 23;
`endif
            trunc_sat23 = sat25(t);
        end
    endfunction

    // Round half-even over 23 fraction bits, then saturate to 25 bits.
    function signed [24:0] rhe_sat23(input signed [63:0] acc);
        reg signed [63:0] t;
        begin
            t = acc >>> 23;
            if (acc[22] && ((|acc[21:0]) || t[0]))
                t = t + 64'sd1;
            rhe_sat23 = sat25(t);
        end
    endfunction

    // --- the datapath: one clocked process, three shared multipliers --------------------------
    reg signed [24:0] ma0, mb0, ma1, mb1, ma2, mb2;
    reg signed [49:0] pr0, pr1, pr2;
    reg signed [63:0] acc;
    reg signed [24:0] res;

    always @(posedge clk) begin
        done <= 1'b0;
        if (rst) begin
            state <= S_IDLE;
            j <= 3'd0;
            k <= 3'd0;
        end else begin
            // Operand multiplexers in front of the three multipliers.
            ma0 = 25'sd0; mb0 = 25'sd0; ma1 = 25'sd0; mb1 = 25'sd0; ma2 = 25'sd0; mb2 = 25'sd0;
            case (state)
                S_ROT: begin
                    ma0 = C; ma1 = S;
                    case (k)   // n0_i = c R_i0 + s R_i1 (k = i); n1_i = c R_i1 - s R_i0 (k = 3 + i)
                        3'd0: begin mb0 = r00; mb1 = r01; end
                        3'd1: begin mb0 = r10; mb1 = r11; end
                        3'd2: begin mb0 = r20; mb1 = r21; end
                        3'd3: begin mb0 = r01; mb1 = r00; end
                        3'd4: begin mb0 = r11; mb1 = r10; end
                        default: begin mb0 = r21; mb1 = r20; end
                    endcase
                end
                S_POS: begin   // p_i + a n0_i + d R_i2
                    ma0 = a_j; ma1 = d_j;
                    case (k)
                        3'd0: begin mb0 = n00; mb1 = r02; end
                        3'd1: begin mb0 = n01; mb1 = r12; end
                        default: begin mb0 = n02; mb1 = r22; end
                    endcase
                end
                S_WROT: begin  // R_i . f (k = i), R_i . m (k = 3 + i)
                    case (k)
                        3'd0, 3'd3: begin ma0 = r00; ma1 = r01; ma2 = r02; end
                        3'd1, 3'd4: begin ma0 = r10; ma1 = r11; ma2 = r12; end
                        default:    begin ma0 = r20; ma1 = r21; ma2 = r22; end
                    endcase
                    if (k < 3'd3) begin
                        mb0 = w0; mb1 = w1; mb2 = w2;
                    end else begin
                        mb0 = w3; mb1 = w4; mb2 = w5;
                    end
                end
                S_MX: begin    // m0_k + (r x f0)_k
                    case (k)
                        3'd0:    begin ma0 = L1; mb0 = f0z; ma1 = L2; mb1 = f0y; end
                        3'd1:    begin ma0 = L2; mb0 = f0x; ma1 = L0; mb1 = f0z; end
                        default: begin ma0 = L0; mb0 = f0y; ma1 = L1; mb1 = f0x; end
                    endcase
                end
                S_TAU: begin   // z_j . mj
                    ma0 = zs[24:0];  mb0 = mj0;
                    ma1 = zs[49:25]; mb1 = mj1;
                    ma2 = zs[74:50]; mb2 = mj2;
                end
                default: ;
            endcase
            pr0 = ma0 * mb0;
            pr1 = ma1 * mb1;
            pr2 = ma2 * mb2;

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
                    k <= 3'd0;
                    state <= S_ANG;
                end
                S_ANG: begin
                    S <= sin_w;
                    C <= cos_w;
                    zs <= {r22, r12, r02, zs[449:75]};
                    os <= {p2, p1, p0, os[575:96]};
                    k <= 3'd0;
                    state <= S_ROT;
                end
                S_ROT: begin
                    acc = (k < 3'd3) ? pr0 + pr1 : pr0 - pr1;
                    res = acc[47:23];                 // truncate 46 -> 23, wrap to 25 bits
                    case (k)
                        3'd0: n00 <= res;
                        3'd1: n01 <= res;
                        3'd2: n02 <= res;
                        3'd3: n10 <= res;
                        3'd4: n11 <= res;
                        default: n12 <= res;
                    endcase
                    if (k == 3'd5) begin
                        k <= 3'd0;
                        state <= S_POS;
                    end else
                        k <= k + 3'd1;
                end
                S_POS: begin
                    case (k)
                        3'd0: acc = ($signed(p0) <<< 17) + pr0 + pr1;
                        3'd1: acc = ($signed(p1) <<< 17) + pr0 + pr1;
                        default: acc = ($signed(p2) <<< 17) + pr0 + pr1;
                    endcase
`ifdef MUTANT_DROP_LSB
                    acc[17] = 1'b0;
`endif
                    case (k)                          // truncate 47 -> 30, wrap to 32 bits
                        3'd0: p0 <= acc[48:17];
                        3'd1: p1 <= acc[48:17];
                        default: p2 <= acc[48:17];
                    endcase
                    if (k == 3'd2) begin
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
                        qs <= qs >> 24; offs <= offs >> 24;
                        as <= as >> 25; ds <= ds >> 25; alphas <= alphas >> 2;
                        k <= 3'd0;
                        if (j == 3'd5) begin
                            j <= 3'd0;
                            if (op_force)
                                state <= S_WROT;
                            else begin
                                state <= S_IDLE;
                                done <= 1'b1;
                            end
                        end else begin
                            j <= j + 3'd1;
                            state <= S_ANG;
                        end
                    end else
                        k <= k + 3'd1;
                end
                S_WROT: begin
                    acc = pr0 + pr1 + pr2;
                    res = trunc_sat23(acc);
                    case (k)
                        3'd0: f0x <= flange ? res : w0;
                        3'd1: f0y <= flange ? res : w1;
                        3'd2: f0z <= flange ? res : w2;
                        3'd3: m0x <= flange ? res : w3;
                        3'd4: m0y <= flange ? res : w4;
                        default: m0z <= flange ? res : w5;
                    endcase
                    if (k == 3'd5) begin
                        L0 <= lever7(p0, os[31:0]);   // joint 0's lever arm
                        L1 <= lever7(p1, os[63:32]);
                        L2 <= lever7(p2, os[95:64]);
                        k <= 3'd0;
                        state <= S_MX;
                    end else
                        k <= k + 3'd1;
                end
                S_MX: begin
                    case (k)
                        3'd0: acc = ($signed(m0x) <<< 23) + pr0 - pr1;
                        3'd1: acc = ($signed(m0y) <<< 23) + pr0 - pr1;
                        default: acc = ($signed(m0z) <<< 23) + pr0 - pr1;
                    endcase
                    res = trunc_sat23(acc);
                    case (k)
                        3'd0: mj0 <= res;
                        3'd1: mj1 <= res;
                        default: mj2 <= res;
                    endcase
                    if (k == 3'd2) begin
                        k <= 3'd0;
                        state <= S_TAU;
                    end else
                        k <= k + 3'd1;
                end
                S_TAU: begin
                    acc = pr0 + pr1 + pr2;
                    taus <= {rhe_sat23(acc), taus[149:25]};
                    zs <= {zs[74:0], zs[449:75]};     // next joint's z_j, o_j to the bottom
                    os <= {os[95:0], os[575:96]};
                    if (j == 3'd5) begin
                        j <= 3'd0;
                        state <= S_IDLE;
                        done <= 1'b1;
                    end else begin
                        L0 <= lever7(p0, os[127:96]); // the next joint's lever arm
                        L1 <= lever7(p1, os[159:128]);
                        L2 <= lever7(p2, os[191:160]);
                        j <= j + 3'd1;
                        state <= S_MX;
                    end
                end
                default: state <= S_IDLE;
            endcase
        end
    end
endmodule
