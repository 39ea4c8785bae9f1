// Sine and cosine of a 24-bit binary angle: quarter-wave table + linear interpolation.
// Bit-exact with penelope_fpga::sincos::sin_cos (fpga/src/sincos.rs); spec in fpga/SPEC.md.
//
//   angle  <+-,24,1> pi-rad: quadrant = angle[23:22], phi = angle[21:0]
//   g(u)   = T[u>>10] + floor(D[u>>10] * u[9:0] / 2^10)      <+,29,1>, u = phi or 2^22 - phi
//   r      = round_half_up(g, 28 -> 23 fraction bits)          <+-,25,2>
//   unfold: q0 (r1, r2)  q1 (r2, -r1)  q2 (-r1, -r2)  q3 (-r2, r1)
//
// Combinational: in penelope_kin the angle comes from registers and the outputs go to
// registers, so sine and cosine take one clock cycle. The ROM is 4097 x 46 bits
// ({T[28:0], D[16:0]}), read at two addresses (a dual-port block RAM in hardware).
`timescale 1ns/1ps
`ifndef SINCOS_TABLE
`define SINCOS_TABLE "sincos_table.hex"
`endif

module kin_sincos (
    input  wire        [23:0] angle,
    output reg  signed [24:0] sin_o,
    output reg  signed [24:0] cos_o
);
    reg [45:0] rom [0:4096];
    initial $readmemh(`SINCOS_TABLE, rom);

    reg [22:0] u1, u2;
    reg [45:0] e1, e2;
    reg [26:0] p1, p2;
    reg [28:0] g1, g2;
    reg [24:0] r1, r2;

    always @* begin
        u1 = {1'b0, angle[21:0]};
        u2 = 23'h400000 - u1;
        e1 = rom[u1[22:10]];
        e2 = rom[u2[22:10]];
        p1 = e1[16:0] * u1[9:0];          // 17 x 10 unsigned, exact
        p2 = e2[16:0] * u2[9:0];
        g1 = e1[45:17] + {12'd0, p1[26:10]};  // T + floor(D f / 2^10); cannot overflow
        g2 = e2[45:17] + {12'd0, p2[26:10]};
`ifdef MUTANT_SINCOS_TRUNC
        r1 = g1 >> 5;                       // planted bug: truncate instead of round half-up
        r2 = g2 >> 5;
`else
        r1 = ({1'b0, g1} + 30'd16) >> 5;    // round half up, 28 -> 23 fraction bits
        r2 = ({1'b0, g2} + 30'd16) >> 5;
`endif
        case (angle[23:22])
            2'd0:    begin sin_o = r1;  cos_o = r2;  end
            2'd1:    begin sin_o = r2;  cos_o = -r1; end
            2'd2:    begin sin_o = -r1; cos_o = -r2; end
            default: begin sin_o = -r2; cos_o = r1;  end
        endcase
    end
endmodule
