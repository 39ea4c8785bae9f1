// Test bench for penelope_kin: streams vectors from a text file through the design and writes
// every result word, plus the measured cycle count, to another. Driven by the Rust
// co-simulation harness (fpga/src/cosim.rs), which compares each word with the Rust model.
//
//   vvp tb_kin +IN=vectors.hex +OUT=results.hex      (Icarus)
//   obj_tb_kin/tb_kin +IN=vectors.hex +OUT=results.hex  (Verilator --binary --timing)
//
// Input, one vector per line, hex words (two's complement, masked to the port width):
//   flags q0..q5 w0..w5 [off0..off5 a0..a5 d0..d5 alpha0..alpha5]
//   flags bit 0 = force_op, bit 1 = flange_frame, bit 2 = a DH table follows (else the
//   previous vector's table is kept)
// Output, one line per vector:
//   r00 r01 r02 r10 .. r22 p0 p1 p2 f0x f0y f0z m0x m0y m0z tau0..tau5 cycles
// `cycles` counts the rising edges from the one that samples `start` to the one that raises
// `done`, both included; the next vector's start is sampled on the very next edge.
`timescale 1ns/1ps
module tb_kin;
    reg clk = 1'b0;
    always #12.5 clk = ~clk;   // 40 MHz

    reg          rst = 1'b1, start = 1'b0, force_op = 1'b0, flange_frame = 1'b0;
    reg  [143:0] q = 0, dh_offset = 0;
    reg  [149:0] wrench = 0, dh_a = 0, dh_d = 0;
    reg  [11:0]  dh_alpha = 0;
    wire         busy, done;
    wire [224:0] rot;
    wire [95:0]  pos;
    wire [149:0] base_wrench, tau;

    penelope_kin dut (
        .clk(clk), .rst(rst), .start(start), .force_op(force_op), .flange_frame(flange_frame),
        .q(q), .wrench(wrench), .dh_offset(dh_offset), .dh_a(dh_a), .dh_d(dh_d),
        .dh_alpha(dh_alpha), .busy(busy), .done(done), .rot(rot), .pos(pos),
        .base_wrench(base_wrench), .tau(tau)
    );

    reg [1023:0] in_name, out_name;
    integer fin, fout, n, r, i, cycles, count;
    reg [31:0] w;
    reg [2:0]  flags;
    realtime   t0;

    initial begin
        if (!$value$plusargs("IN=%s", in_name) || !$value$plusargs("OUT=%s", out_name)) begin
            $display("usage: vvp tb_kin +IN=vectors +OUT=results");
            $finish;
        end
        fin = $fopen(in_name, "r");
        fout = $fopen(out_name, "w");
        if (fin == 0 || fout == 0) begin
            $display("ERROR: cannot open the vector files");
            $finish;
        end
        @(negedge clk); @(negedge clk);
        rst = 1'b0;
        count = 0;
        r = $fscanf(fin, "%h", w);
        while (r == 1) begin
            flags = w[2:0];
            force_op = flags[0];
            flange_frame = flags[1];
            for (i = 0; i < 6; i = i + 1) begin r = $fscanf(fin, "%h", w); q[24*i +: 24] = w[23:0]; end
            for (i = 0; i < 6; i = i + 1) begin r = $fscanf(fin, "%h", w); wrench[25*i +: 25] = w[24:0]; end
            if (flags[2]) begin
                for (i = 0; i < 6; i = i + 1) begin r = $fscanf(fin, "%h", w); dh_offset[24*i +: 24] = w[23:0]; end
                for (i = 0; i < 6; i = i + 1) begin r = $fscanf(fin, "%h", w); dh_a[25*i +: 25] = w[24:0]; end
                for (i = 0; i < 6; i = i + 1) begin r = $fscanf(fin, "%h", w); dh_d[25*i +: 25] = w[24:0]; end
                for (i = 0; i < 6; i = i + 1) begin r = $fscanf(fin, "%h", w); dh_alpha[2*i +: 2] = w[1:0]; end
            end
            if (busy) begin
                $display("ERROR: busy at start");
                $finish;
            end
            start = 1'b1;
            t0 = $realtime;                  // a falling edge: the next rising edge samples start
            @(negedge clk);
            start = 1'b0;
            if (!done) @(posedge done);
            @(negedge clk);                  // the falling edge after the one that raised done
            cycles = $rtoi(($realtime - t0) / 25.0);
            for (i = 0; i < 9; i = i + 1) $fwrite(fout, "%h ", rot[25*i +: 25]);
            for (i = 0; i < 3; i = i + 1) $fwrite(fout, "%h ", pos[32*i +: 32]);
            for (i = 0; i < 6; i = i + 1) $fwrite(fout, "%h ", base_wrench[25*i +: 25]);
            for (i = 0; i < 6; i = i + 1) $fwrite(fout, "%h ", tau[25*i +: 25]);
            $fwrite(fout, "%0d\n", cycles);
            count = count + 1;
            r = $fscanf(fin, "%h", w);
        end
        $fclose(fout);
        $display("DONE %0d", count);
        $finish;
    end
endmodule
