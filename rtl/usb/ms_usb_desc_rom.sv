// ms_usb_desc_rom: descriptor ROM of the Multisonar USB device (device, configuration with one
// vendor interface and two bulk endpoints, strings, BOS with the Microsoft OS 2.0 platform
// capability, and the MS OS 2.0 descriptor set: compatible ID "WINUSB" + DeviceInterfaceGUIDs).
// Offsets and lengths of each descriptor are DESC_*_OFF / DESC_*_LEN in ms_usb_pkg; the byte
// layout is listed in docs/usb_core.md.
//
// Timing contract: synchronous read, data_o shows the byte at addr_i of the previous clock.
// Parameters: VID, PID, BCD_DEVICE (bcdDevice = protocol version; its major digit ends the
// interface string "Multisonar protocol vN"), SERIAL (the serial-number string is its 8
// upper-case hex digits), MS_VENDOR_CODE (bRequest of the MS OS 2.0 vendor request).
// The case table was generated once from a Python description of the descriptors; edit it
// together with the offsets in ms_usb_pkg.
module ms_usb_desc_rom #(
  parameter int VID            = 'h1209,
  parameter int PID            = 'h0001,
  parameter int BCD_DEVICE     = 'h0100,
  parameter int SERIAL         = 'h00000001,
  parameter int MS_VENDOR_CODE = 'h4D
) (
  input  logic       clk_i,
  input  logic [8:0] addr_i,
  output logic [7:0] data_o
);
  function automatic logic [7:0] hex_char(input logic [3:0] n);
    hex_char = (n < 4'd10) ? 8'h30 + {4'd0, n} : 8'h37 + {4'd0, n};
  endfunction

  logic [7:0] b;
  // In logic, not block RAM (yosys' proc_rom copies the case's attributes onto the ROM it
  // infers): about 270 LUT4 instead of one of the LFE5U-25F's 56 DP16KD, which the design needs.
  always_comb begin
    (* rom_style = "logic" *)
    case (addr_i)
      9'd0: b = 8'h12;                          9'd1: b = 8'h01;                          9'd2: b = 8'h01;
      9'd3: b = 8'h02;                          9'd4: b = 8'h00;                          9'd5: b = 8'h00;
      9'd6: b = 8'h00;                          9'd7: b = 8'h40;                          9'd8: b = VID[7:0];
      9'd9: b = VID[15:8];                      9'd10: b = PID[7:0];                      9'd11: b = PID[15:8];
      9'd12: b = BCD_DEVICE[7:0];               9'd13: b = BCD_DEVICE[15:8];              9'd14: b = 8'h01;
      9'd15: b = 8'h02;                         9'd16: b = 8'h03;                         9'd17: b = 8'h01;
      9'd18: b = 8'h09;                         9'd19: b = 8'h02;                         9'd20: b = 8'h20;
      9'd21: b = 8'h00;                         9'd22: b = 8'h01;                         9'd23: b = 8'h01;
      9'd24: b = 8'h00;                         9'd25: b = 8'h80;                         9'd26: b = 8'h32;
      9'd27: b = 8'h09;                         9'd28: b = 8'h04;                         9'd29: b = 8'h00;
      9'd30: b = 8'h00;                         9'd31: b = 8'h02;                         9'd32: b = 8'hFF;
      9'd33: b = 8'h00;                         9'd34: b = 8'h00;                         9'd35: b = 8'h04;
      9'd36: b = 8'h07;                         9'd37: b = 8'h05;                         9'd38: b = 8'h01;
      9'd39: b = 8'h02;                         9'd40: b = 8'h40;                         9'd41: b = 8'h00;
      9'd42: b = 8'h00;                         9'd43: b = 8'h07;                         9'd44: b = 8'h05;
      9'd45: b = 8'h81;                         9'd46: b = 8'h02;                         9'd47: b = 8'h40;
      9'd48: b = 8'h00;                         9'd49: b = 8'h00;                         9'd50: b = 8'h04;
      9'd51: b = 8'h03;                         9'd52: b = 8'h09;                         9'd53: b = 8'h04;
      9'd54: b = 8'h16;                         9'd55: b = 8'h03;                         9'd56: b = 8'h4D;
      9'd57: b = 8'h00;                         9'd58: b = 8'h75;                         9'd59: b = 8'h00;
      9'd60: b = 8'h6C;                         9'd61: b = 8'h00;                         9'd62: b = 8'h74;
      9'd63: b = 8'h00;                         9'd64: b = 8'h69;                         9'd65: b = 8'h00;
      9'd66: b = 8'h73;                         9'd67: b = 8'h00;                         9'd68: b = 8'h6F;
      9'd69: b = 8'h00;                         9'd70: b = 8'h6E;                         9'd71: b = 8'h00;
      9'd72: b = 8'h61;                         9'd73: b = 8'h00;                         9'd74: b = 8'h72;
      9'd75: b = 8'h00;                         9'd76: b = 8'h38;                         9'd77: b = 8'h03;
      9'd78: b = 8'h4D;                         9'd79: b = 8'h00;                         9'd80: b = 8'h75;
      9'd81: b = 8'h00;                         9'd82: b = 8'h6C;                         9'd83: b = 8'h00;
      9'd84: b = 8'h74;                         9'd85: b = 8'h00;                         9'd86: b = 8'h69;
      9'd87: b = 8'h00;                         9'd88: b = 8'h73;                         9'd89: b = 8'h00;
      9'd90: b = 8'h6F;                         9'd91: b = 8'h00;                         9'd92: b = 8'h6E;
      9'd93: b = 8'h00;                         9'd94: b = 8'h61;                         9'd95: b = 8'h00;
      9'd96: b = 8'h72;                         9'd97: b = 8'h00;                         9'd98: b = 8'h20;
      9'd99: b = 8'h00;                         9'd100: b = 8'h32;                        9'd101: b = 8'h00;
      9'd102: b = 8'h34;                        9'd103: b = 8'h00;                        9'd104: b = 8'h2D;
      9'd105: b = 8'h00;                        9'd106: b = 8'h65;                        9'd107: b = 8'h00;
      9'd108: b = 8'h6C;                        9'd109: b = 8'h00;                        9'd110: b = 8'h65;
      9'd111: b = 8'h00;                        9'd112: b = 8'h6D;                        9'd113: b = 8'h00;
      9'd114: b = 8'h65;                        9'd115: b = 8'h00;                        9'd116: b = 8'h6E;
      9'd117: b = 8'h00;                        9'd118: b = 8'h74;                        9'd119: b = 8'h00;
      9'd120: b = 8'h20;                        9'd121: b = 8'h00;                        9'd122: b = 8'h73;
      9'd123: b = 8'h00;                        9'd124: b = 8'h6F;                        9'd125: b = 8'h00;
      9'd126: b = 8'h6E;                        9'd127: b = 8'h00;                        9'd128: b = 8'h61;
      9'd129: b = 8'h00;                        9'd130: b = 8'h72;                        9'd131: b = 8'h00;
      9'd132: b = 8'h12;                        9'd133: b = 8'h03;                        9'd134: b = hex_char(SERIAL[31:28]);
      9'd135: b = 8'h00;                        9'd136: b = hex_char(SERIAL[27:24]);      9'd137: b = 8'h00;
      9'd138: b = hex_char(SERIAL[23:20]);      9'd139: b = 8'h00;                        9'd140: b = hex_char(SERIAL[19:16]);
      9'd141: b = 8'h00;                        9'd142: b = hex_char(SERIAL[15:12]);      9'd143: b = 8'h00;
      9'd144: b = hex_char(SERIAL[11:8]);       9'd145: b = 8'h00;                        9'd146: b = hex_char(SERIAL[7:4]);
      9'd147: b = 8'h00;                        9'd148: b = hex_char(SERIAL[3:0]);        9'd149: b = 8'h00;
      9'd150: b = 8'h2E;                        9'd151: b = 8'h03;                        9'd152: b = 8'h4D;
      9'd153: b = 8'h00;                        9'd154: b = 8'h75;                        9'd155: b = 8'h00;
      9'd156: b = 8'h6C;                        9'd157: b = 8'h00;                        9'd158: b = 8'h74;
      9'd159: b = 8'h00;                        9'd160: b = 8'h69;                        9'd161: b = 8'h00;
      9'd162: b = 8'h73;                        9'd163: b = 8'h00;                        9'd164: b = 8'h6F;
      9'd165: b = 8'h00;                        9'd166: b = 8'h6E;                        9'd167: b = 8'h00;
      9'd168: b = 8'h61;                        9'd169: b = 8'h00;                        9'd170: b = 8'h72;
      9'd171: b = 8'h00;                        9'd172: b = 8'h20;                        9'd173: b = 8'h00;
      9'd174: b = 8'h70;                        9'd175: b = 8'h00;                        9'd176: b = 8'h72;
      9'd177: b = 8'h00;                        9'd178: b = 8'h6F;                        9'd179: b = 8'h00;
      9'd180: b = 8'h74;                        9'd181: b = 8'h00;                        9'd182: b = 8'h6F;
      9'd183: b = 8'h00;                        9'd184: b = 8'h63;                        9'd185: b = 8'h00;
      9'd186: b = 8'h6F;                        9'd187: b = 8'h00;                        9'd188: b = 8'h6C;
      9'd189: b = 8'h00;                        9'd190: b = 8'h20;                        9'd191: b = 8'h00;
      9'd192: b = 8'h76;                        9'd193: b = 8'h00;                        9'd194: b = hex_char(BCD_DEVICE[11:8]);
      9'd195: b = 8'h00;                        9'd196: b = 8'h05;                        9'd197: b = 8'h0F;
      9'd198: b = 8'h21;                        9'd199: b = 8'h00;                        9'd200: b = 8'h01;
      9'd201: b = 8'h1C;                        9'd202: b = 8'h10;                        9'd203: b = 8'h05;
      9'd204: b = 8'h00;                        9'd205: b = 8'hDF;                        9'd206: b = 8'h60;
      9'd207: b = 8'hDD;                        9'd208: b = 8'hD8;                        9'd209: b = 8'h89;
      9'd210: b = 8'h45;                        9'd211: b = 8'hC7;                        9'd212: b = 8'h4C;
      9'd213: b = 8'h9C;                        9'd214: b = 8'hD2;                        9'd215: b = 8'h65;
      9'd216: b = 8'h9D;                        9'd217: b = 8'h9E;                        9'd218: b = 8'h64;
      9'd219: b = 8'h8A;                        9'd220: b = 8'h9F;                        9'd221: b = 8'h00;
      9'd222: b = 8'h00;                        9'd223: b = 8'h03;                        9'd224: b = 8'h06;
      9'd225: b = 8'hA2;                        9'd226: b = 8'h00;                        9'd227: b = MS_VENDOR_CODE[7:0];
      9'd228: b = 8'h00;                        9'd229: b = 8'h0A;                        9'd230: b = 8'h00;
      9'd231: b = 8'h00;                        9'd232: b = 8'h00;                        9'd233: b = 8'h00;
      9'd234: b = 8'h00;                        9'd235: b = 8'h03;                        9'd236: b = 8'h06;
      9'd237: b = 8'hA2;                        9'd238: b = 8'h00;                        9'd239: b = 8'h14;
      9'd240: b = 8'h00;                        9'd241: b = 8'h03;                        9'd242: b = 8'h00;
      9'd243: b = 8'h57;                        9'd244: b = 8'h49;                        9'd245: b = 8'h4E;
      9'd246: b = 8'h55;                        9'd247: b = 8'h53;                        9'd248: b = 8'h42;
      9'd249: b = 8'h00;                        9'd250: b = 8'h00;                        9'd251: b = 8'h00;
      9'd252: b = 8'h00;                        9'd253: b = 8'h00;                        9'd254: b = 8'h00;
      9'd255: b = 8'h00;                        9'd256: b = 8'h00;                        9'd257: b = 8'h00;
      9'd258: b = 8'h00;                        9'd259: b = 8'h84;                        9'd260: b = 8'h00;
      9'd261: b = 8'h04;                        9'd262: b = 8'h00;                        9'd263: b = 8'h07;
      9'd264: b = 8'h00;                        9'd265: b = 8'h2A;                        9'd266: b = 8'h00;
      9'd267: b = 8'h44;                        9'd268: b = 8'h00;                        9'd269: b = 8'h65;
      9'd270: b = 8'h00;                        9'd271: b = 8'h76;                        9'd272: b = 8'h00;
      9'd273: b = 8'h69;                        9'd274: b = 8'h00;                        9'd275: b = 8'h63;
      9'd276: b = 8'h00;                        9'd277: b = 8'h65;                        9'd278: b = 8'h00;
      9'd279: b = 8'h49;                        9'd280: b = 8'h00;                        9'd281: b = 8'h6E;
      9'd282: b = 8'h00;                        9'd283: b = 8'h74;                        9'd284: b = 8'h00;
      9'd285: b = 8'h65;                        9'd286: b = 8'h00;                        9'd287: b = 8'h72;
      9'd288: b = 8'h00;                        9'd289: b = 8'h66;                        9'd290: b = 8'h00;
      9'd291: b = 8'h61;                        9'd292: b = 8'h00;                        9'd293: b = 8'h63;
      9'd294: b = 8'h00;                        9'd295: b = 8'h65;                        9'd296: b = 8'h00;
      9'd297: b = 8'h47;                        9'd298: b = 8'h00;                        9'd299: b = 8'h55;
      9'd300: b = 8'h00;                        9'd301: b = 8'h49;                        9'd302: b = 8'h00;
      9'd303: b = 8'h44;                        9'd304: b = 8'h00;                        9'd305: b = 8'h73;
      9'd306: b = 8'h00;                        9'd307: b = 8'h00;                        9'd308: b = 8'h00;
      9'd309: b = 8'h50;                        9'd310: b = 8'h00;                        9'd311: b = 8'h7B;
      9'd312: b = 8'h00;                        9'd313: b = 8'h38;                        9'd314: b = 8'h00;
      9'd315: b = 8'h43;                        9'd316: b = 8'h00;                        9'd317: b = 8'h36;
      9'd318: b = 8'h00;                        9'd319: b = 8'h41;                        9'd320: b = 8'h00;
      9'd321: b = 8'h31;                        9'd322: b = 8'h00;                        9'd323: b = 8'h45;
      9'd324: b = 8'h00;                        9'd325: b = 8'h32;                        9'd326: b = 8'h00;
      9'd327: b = 8'h44;                        9'd328: b = 8'h00;                        9'd329: b = 8'h2D;
      9'd330: b = 8'h00;                        9'd331: b = 8'h35;                        9'd332: b = 8'h00;
      9'd333: b = 8'h42;                        9'd334: b = 8'h00;                        9'd335: b = 8'h33;
      9'd336: b = 8'h00;                        9'd337: b = 8'h46;                        9'd338: b = 8'h00;
      9'd339: b = 8'h2D;                        9'd340: b = 8'h00;                        9'd341: b = 8'h34;
      9'd342: b = 8'h00;                        9'd343: b = 8'h41;                        9'd344: b = 8'h00;
      9'd345: b = 8'h37;                        9'd346: b = 8'h00;                        9'd347: b = 8'h45;
      9'd348: b = 8'h00;                        9'd349: b = 8'h2D;                        9'd350: b = 8'h00;
      9'd351: b = 8'h39;                        9'd352: b = 8'h00;                        9'd353: b = 8'h44;
      9'd354: b = 8'h00;                        9'd355: b = 8'h32;                        9'd356: b = 8'h00;
      9'd357: b = 8'h31;                        9'd358: b = 8'h00;                        9'd359: b = 8'h2D;
      9'd360: b = 8'h00;                        9'd361: b = 8'h36;                        9'd362: b = 8'h00;
      9'd363: b = 8'h46;                        9'd364: b = 8'h00;                        9'd365: b = 8'h30;
      9'd366: b = 8'h00;                        9'd367: b = 8'h42;                        9'd368: b = 8'h00;
      9'd369: b = 8'h33;                        9'd370: b = 8'h00;                        9'd371: b = 8'h43;
      9'd372: b = 8'h00;                        9'd373: b = 8'h34;                        9'd374: b = 8'h00;
      9'd375: b = 8'h45;                        9'd376: b = 8'h00;                        9'd377: b = 8'h35;
      9'd378: b = 8'h00;                        9'd379: b = 8'h41;                        9'd380: b = 8'h00;
      9'd381: b = 8'h37;                        9'd382: b = 8'h00;                        9'd383: b = 8'h31;
      9'd384: b = 8'h00;                        9'd385: b = 8'h7D;                        9'd386: b = 8'h00;
      9'd387: b = 8'h00;                        9'd388: b = 8'h00;                        9'd389: b = 8'h00;
      9'd390: b = 8'h00;
      default: b = 8'h00;
    endcase
  end

  always_ff @(posedge clk_i) data_o <= b;
endmodule
