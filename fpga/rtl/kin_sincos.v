// Sine and cosine of a 24-bit binary angle: quarter-wave table + linear interpolation.
// Bit-exact with penelope_fpga::sincos::sin_cos (fpga/src/sincos.rs); spec in fpga/SPEC.md.
//
//   angle  <+-,24,1> pi-rad: quadrant = angle[23:22], phi = angle[21:0]
//   g(u)   = T[u>>10] + floor(D[u>>10] * u[9:0] / 2^10)      <+,29,1>, u = phi or 2^22 - phi
//   r      = round_half_up(g, 28 -> 23 fraction bits)          <+-,25,2>
//   unfold: q0 (r1, r2)  q1 (r2, -r1)  q2 (-r1, -r2)  q3 (-r2, r1)
//
// Three pipeline stages:
//   edge 1  the table ROM registers the words at u1 >> 10 and u2 >> 10 (a dual-port block RAM
//           with registered read, 4096 x 46 bits); the quadrant, the interpolation fractions and
//           the u2 = 2^22 flag are registered beside it.
//   edge 2  the 17 x 10 products D f (one MULT18X18 per port) and T are registered.
//   edge 3  when `load` is high, sin_o and cos_o take the interpolated, rounded, unfolded words
//           of the angle sampled on edge 1.
// `load` low holds the outputs (penelope_kin keeps a joint's sine and cosine in them while the
// next joint's angle is already in the first two stages). The split keeps the block RAM's
// clock-to-out, its output multiplexer and the multiplier out of the same cycle as the three
// carry chains (interpolation sum, rounding, negation).
//
// The table's last point T[4096] = 2^28 (D[4096] = 0) is not stored: u = 2^22 occurs only as
// u2 for phi = 0, where g = T[4096] exactly, so the ROM is a power of two deep (4096 rows
// instead of 4097, which would double it to 8192).
`timescale 1ns/1ps
`ifndef SINCOS_TABLE
`define SINCOS_TABLE "sincos_table.hex"
`endif

module kin_sincos (
    input  wire               clk,
    input  wire        [23:0] angle,
    input  wire               load,
    output reg  signed [24:0] sin_o,
    output reg  signed [24:0] cos_o
);
    (* rom_style = "block" *) reg [45:0] rom [0:4095];
    initial $readmemh(`SINCOS_TABLE, rom);

    // --- stage 1: addresses into the ROM (registered read) ----------------------------------
    wire [22:0] u1 = {1'b0, angle[21:0]};
    wire [22:0] u2 = 23'h400000 - u1;

    reg [45:0] e1, e2;                  // {T[28:0], D[16:0]} at u1 >> 10, u2 >> 10
    reg [9:0]  f1, f2;                  // interpolation fractions u[9:0]
    reg        top2;                    // u2 = 2^22 (phi = 0): g2 = T[4096] = 2^28
    reg [1:0]  quad;

    always @(posedge clk) begin
        e1 <= rom[u1[21:10]];
        e2 <= rom[u2[21:10]];
        f1 <= u1[9:0];
        f2 <= u2[9:0];
        top2 <= u2[22];
        quad <= angle[23:22];
    end

    // --- stage 2: the interpolation products ------------------------------------------------
    reg [26:0] p1, p2;                  // D f, 17 x 10 unsigned, exact
    reg [28:0] t1, t2;                  // T
    reg        top2b;
    reg [1:0]  quadb;
    always @(posedge clk) begin
        p1 <= {10'd0, e1[16:0]} * {17'd0, f1};
        p2 <= {10'd0, e2[16:0]} * {17'd0, f2};
        t1 <= e1[45:17];
        t2 <= e2[45:17];
        top2b <= top2;
        quadb <= quad;
    end

    // --- stage 3: interpolate, round, unfold ------------------------------------------------
    wire [28:0] g1 = t1 + {12'd0, p1[26:10]};   // T + floor(D f / 2^10); cannot overflow
    wire [28:0] g2 = top2b ? 29'h10000000 : t2 + {12'd0, p2[26:10]};
`ifdef MUTANT_SINCOS_TRUNC
    wire [29:0] h1 = {1'b0, g1};        // planted bug: truncate instead of round half-up
    wire [29:0] h2 = {1'b0, g2};
`else
    wire [29:0] h1 = {1'b0, g1} + 30'd16;   // round half up, 28 -> 23 fraction bits
    wire [29:0] h2 = {1'b0, g2} + 30'd16;
`endif
    // h >> 5 <= 2^23 + 1 fits 25 bits; bits [29:29] are zero (g <= 2^28).
    wire signed [24:0] r1 = {1'b0, h1[28:5]};
    wire signed [24:0] r2 = {1'b0, h2[28:5]};

    always @(posedge clk) begin
        if (load) begin
            case (quadb)
                2'd0:    begin sin_o <= r1;  cos_o <= r2;  end
                2'd1:    begin sin_o <= r2;  cos_o <= -r1; end
                2'd2:    begin sin_o <= -r1; cos_o <= -r2; end
                default: begin sin_o <= -r2; cos_o <= r1;  end
            endcase
        end
    end

    // h1[29] and h2[29] are zero by range (g <= 2^28), the low product bits are the truncated
    // fraction: both deliberately unused.
    wire _unused = &{1'b0, h1[29], h1[4:0], h2[29], h2[4:0], p1[9:0], p2[9:0]};
endmodule
