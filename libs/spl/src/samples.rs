//! Packets built by hand from the protocol pages (`shared/protocols/`), with a distinct known
//! value at every offset, independent of this crate's encoders: for tests and benchmarks of the
//! decoders and of the processes that receive them.

/// Write `bytes` at `off` in `b`: byte placement of its own, independent of the codecs.
fn at(b: &mut [u8], off: usize, bytes: &[u8]) {
    b[off..off + bytes.len()].copy_from_slice(bytes);
}

/// A packet built by hand from the protocol page's table, with a distinct known value at
/// every offset, including garbage in the ignored bytes and in unused obstacle slots.
pub fn debug_packet() -> Vec<u8> {
    let mut b = vec![0u8; 356];
    at(&mut b, 0, &[0xFF; 8]); // vtable pointer: NaN as f64; must be ignored
    at(&mut b, 8, b"RGrt");
    b[12] = 4;
    b[13] = 2; // player
    b[14] = 17; // team
    b[15] = 1; // fallen
    at(&mut b, 16, &(-1234.5f32).to_le_bytes());
    at(&mut b, 20, &(987.25f32).to_le_bytes());
    at(&mut b, 24, &(1.5f32).to_le_bytes());
    at(&mut b, 28, &(2.75f32).to_le_bytes()); // ball age
    at(&mut b, 32, &(3000.0f32).to_le_bytes());
    at(&mut b, 36, &(-1500.0f32).to_le_bytes());
    at(&mut b, 40, &348u16.to_le_bytes());
    b[42] = 18; // controlled
    b[43] = 3; // three obstacles
    at(&mut b, 44, &[3, 4, 6]); // opponent, teammate, fallen opponent
    b[47] = 99; // unused slot: garbage type, must be ignored
    for (i, (x, y, t)) in [
        (100.0f32, 200.0f32, 1000u32),
        (-300.0, 400.0, 70_000),
        (500.0, -600.0, 4_000_000_000),
    ]
    .iter()
    .enumerate()
    {
        at(&mut b, 64 + 4 * i, &x.to_le_bytes());
        at(&mut b, 144 + 4 * i, &y.to_le_bytes());
        at(&mut b, 224 + 4 * i, &t.to_le_bytes());
    }
    at(&mut b, 64 + 4 * 3, &f32::NAN.to_le_bytes()); // unused slot: NaN, ignored
    at(&mut b, 304, &1100u16.to_le_bytes()); // budget
    at(&mut b, 306, &75u16.to_le_bytes()); // secs remaining
    at(&mut b, 308, &[1, 0]); // arm contact
    at(&mut b, 310, &[2, 3]); // push direction
    at(&mut b, 312, &123_456u32.to_le_bytes());
    at(&mut b, 316, &654_321u32.to_le_bytes());
    at(&mut b, 320, &2500u32.to_le_bytes()); // since whistle
    b[324] = 2; // whistle detected
    at(&mut b, 325, &[0xAA; 3]); // padding, ignored
    at(&mut b, 328, &(-2000.0f32).to_le_bytes()); // team ball
    at(&mut b, 332, &(250.0f32).to_le_bytes());
    at(&mut b, 336, &(120.0f32).to_le_bytes()); // team ball velocity
    at(&mut b, 340, &(-60.0f32).to_le_bytes());
    at(&mut b, 344, &(0.8f32).to_le_bytes()); // battery
    at(&mut b, 348, &(55.5f32).to_le_bytes()); // temperature
    b[352] = 7; // referee gesture
    at(&mut b, 353, &[0xBB; 3]); // padding
    b
}

/// A packet built by hand from the protocol page, a known value at every offset.
pub fn gamecontroller_packet() -> Vec<u8> {
    let mut b = vec![0u8; 118];
    b[0..4].copy_from_slice(b"RGme");
    b[4] = 18;
    b[5] = 201; // packet number
    b[6] = 2; // players per team
    b[7] = 1; // playoff
    b[8] = 1; // shared autonomy
    b[9] = 2; // overtime
    b[10] = 3; // PLAYING
    b[11] = 4; // kick-in
    b[12] = 1; // first half
    b[13] = 42; // kicking team
    b[14..16].copy_from_slice(&(-12i16).to_le_bytes());
    b[16..18].copy_from_slice(&(25i16).to_le_bytes());
    // Team 0: number 7, the opponents.
    b[18] = 7;
    b[19] = 1;
    b[20] = 2;
    b[21] = 1;
    b[22] = 3; // score
    b[23] = 0;
    b[24..26].copy_from_slice(&0x0102u16.to_le_bytes());
    b[26..28].copy_from_slice(&900u16.to_le_bytes());
    // Team 1: number 42, us.
    b[68] = 42;
    b[69] = 5;
    b[70] = 6;
    b[71] = 1;
    b[72] = 4; // score
    b[73] = 2;
    b[74..76].copy_from_slice(&0x0304u16.to_le_bytes());
    b[76..78].copy_from_slice(&1150u16.to_le_bytes());
    // Every player slot of both teams: a distinct penalty code (cycling through all 16
    // codes, 12 and 13 being unknown) and a distinct countdown.
    for team in 0..2 {
        for i in 0..20 {
            b[18 + 50 * team + 10 + 2 * i] = ((i + 7 * team) % 16) as u8;
            b[18 + 50 * team + 11 + 2 * i] = (100 * team + i + 1) as u8;
        }
    }
    b
}
