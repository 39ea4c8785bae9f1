// Test bench for kin_sincos: sweeps binary angles, one per clock cycle through the three-stage
// pipeline (each angle's result is read three edges after the angle is applied), and writes, per
// block of 2^16 consecutive angles, a 64-bit hash of the outputs (or, with +DUMP, every output). Driven by the Rust
// co-simulation harness (fpga/src/cosim.rs), which computes the same hashes from the model.
//
//   vvp tb_sincos +START=<first angle, hex 24 bits> +BLOCKS=<n> +OUT=file [+DUMP]
//   (or the same plusargs to the executable Verilator builds)
//
// Hash of a block: h = 0; for each angle a: h = h * 0x9E3779B97F4A7C15 + {sin, cos} (mod 2^64),
// where {sin, cos} is the 50-bit concatenation of the two 25-bit words. The multiplier is odd,
// so any single differing output changes the hash.
`timescale 1ns/1ps
module tb_sincos;
    reg         clk = 1'b0;
    reg  [23:0] angle;
    wire signed [24:0] s, c;
    kin_sincos dut (.clk(clk), .angle(angle), .load(1'b1), .sin_o(s), .cos_o(c));

    task tick;   // one clock cycle, 25 ns (40 MHz)
        begin
            #12.5 clk = 1'b1;
            #12.5 clk = 1'b0;
        end
    endtask

    reg [1023:0] out_name;
    reg [63:0] h;
    reg [23:0] first;
    integer blocks, b, k, fout, dump;

    initial begin
        if (!$value$plusargs("START=%h", first) || !$value$plusargs("BLOCKS=%d", blocks)
            || !$value$plusargs("OUT=%s", out_name)) begin
            $display("usage: vvp tb_sincos +START=hex +BLOCKS=n +OUT=file [+DUMP]");
            $finish;
        end
        dump = $test$plusargs("DUMP");
        fout = $fopen(out_name, "w");
        angle = first;
        tick;                                // the ROM stage samples the first angle,
        angle = angle + 24'd1;
        tick;                                // the product stage takes it
        for (b = 0; b < blocks; b = b + 1) begin
            h = 64'd0;
            for (k = 0; k < 65536; k = k + 1) begin
                angle = angle + 24'd1;       // the next angle enters the ROM stage ...
                tick;                        // ... while the one two before is loaded
                if (dump != 0)
                    $fwrite(fout, "%h %h %h\n", angle - 24'd2, s, c);
                else
                    h = h * 64'h9E3779B97F4A7C15 + {14'd0, s, c};
            end
            if (dump == 0)
                $fwrite(fout, "%h\n", h);
        end
        $fclose(fout);
        $display("DONE %0d", blocks);
        $finish;
    end
endmodule
