#!/usr/bin/env python3
"""room_scene: speech and rooms for the recognition tests and benchmarks, made by tools marie did
not write: espeak-ng speaks the phrases (six voices, none Festival's), pyroomacoustics renders a
shoebox room with the reverberation asked for (image sources, absorption from Sabine's formula)
around marie's default 8-microphone array.

  room_scene.py voices OUTDIR
      cmd_V_II.wav (the 20 commands), oog_V_II.wav (phrases out of the grammar), V = voice 0..5
  room_scene.py scene --rt60 S --snr DB --utterances N --seed K VOICES OUT.wav OUT.tsv
      a continuous scene: N utterances (commands, phrases out of the grammar, real recordings,
      noise bursts) from several places with pauses, a fan running all along; OUT.tsv says
      what was said when (start_s end_s kind text bearing_deg).
"""
import io
import math
import os
import subprocess
import sys
import wave

import numpy as np
from scipy.signal import fftconvolve, lfilter, resample_poly

RATE = 16000
COMMANDS = ["go to room a", "go to room b", "go to room c", "go to the kitchen", "stop", "come here",
            "follow me", "turn left", "turn right", "go forward", "go back", "where are you going",
            "what is your name", "hello robot", "goodbye", "face me", "wait here", "go home",
            "start the mission", "cancel the mission"]
OUT_OF_GRAMMAR = ["room service please", "good morning everyone", "the weather is nice today",
                  "can you bring me a coffee", "i left my keys in the car", "turn on the lights",
                  "go to the garden", "where is the kitchen", "what time is it", "hello there",
                  "stop the music", "open the door", "thank you very much", "see you tomorrow",
                  "let us go home now", "the meeting starts at ten"]
# espeak-ng voices and variants: American, British, Scottish, Caribbean, received pronunciation,
# New York; three of them with female variants.
VOICES = ["en-us", "en-gb+f3", "en-gb-scotland+m3", "en-029+f2", "en-gb-x-rp+m5", "en-us-nyc+f4"]
# marie's default array (hw/audio/micarray.h, MICARRAY_DEFAULT): 8 on a 0.16 m circle, heights
# alternating 0.60 and 0.70 m.
MICS = [(0.16 * math.cos(k * math.pi / 4), 0.16 * math.sin(k * math.pi / 4), 0.60 if k % 2 == 0 else 0.70)
        for k in range(8)]


def read_wav(path):
    with wave.open(path) as w:
        x = np.frombuffer(w.readframes(w.getnframes()), dtype=np.int16).astype(np.float64) / 32768
        if w.getnchannels() > 1:
            x = x.reshape(-1, w.getnchannels())[:, 0]
        rate = w.getframerate()
    return x if rate == RATE else resample_poly(x, RATE, rate)


def write_wav(path, x, channels=1):
    y = np.clip(np.round(x * 32767), -32768, 32767).astype("<i2")
    with wave.open(path, "wb") as w:
        w.setnchannels(channels)
        w.setsampwidth(2)
        w.setframerate(RATE)
        w.writeframes(y.tobytes())


def espeak(text, voice):
    out = subprocess.run(["espeak-ng", "-v", voice, "-s", "150", "--stdout", text], capture_output=True, check=True)
    with wave.open(io.BytesIO(out.stdout)) as w:
        rate = w.getframerate()
        x = np.frombuffer(w.readframes(w.getnframes()), dtype=np.int16).astype(np.float64) / 32768
    return resample_poly(x, RATE, rate)


def cmd_voices(outdir):
    os.makedirs(outdir, exist_ok=True)
    for v, voice in enumerate(VOICES):
        for i, text in enumerate(COMMANDS):
            write_wav(os.path.join(outdir, "cmd_%d_%02d.wav" % (v, i)), 0.5 * espeak(text, voice))
        for i, text in enumerate(OUT_OF_GRAMMAR):
            write_wav(os.path.join(outdir, "oog_%d_%02d.wav" % (v, i)), 0.5 * espeak(text, voice))


def real_recordings(datadir):
    """The real recordings of tests/data/speech (README there): out of the robot's grammar."""
    out = []
    for line in open(os.path.join(datadir, "transcripts.tsv")):
        if line.strip() and not line.startswith("#"):
            name, text = line.rstrip("\n").split("\t", 1)
            out.append((read_wav(os.path.join(datadir, name)), text))
    return out


def fan(n, rng):
    """A fan, as marie's simulator makes one: noise below about 1 kHz and the hum of its blades."""
    a = math.exp(-2 * math.pi * 1000 / RATE)
    lp = lfilter([1 - a], [1, -a], rng.standard_normal(n))
    t = np.arange(n) / RATE
    return 3 * lp + 0.3 * np.sin(2 * np.pi * 100 * t) + 0.2 * np.sin(2 * np.pi * 200 * t + 1) + 0.1 * np.sin(2 * np.pi * 300 * t + 2)


def burst(rng):
    """Noise that is not speech: a knock, a dropped object, a door (decaying filtered noise)."""
    n = int(rng.uniform(0.15, 0.8) * RATE)
    a = rng.uniform(0.3, 0.95)
    x = lfilter([1 - a], [1, -a], rng.standard_normal(n)) * np.exp(-np.arange(n) / (rng.uniform(0.05, 0.3) * RATE))
    return x


def active_rms(x):
    """RMS over the 50 ms windows within 30 dB of the loudest one (the voiced part)."""
    w = 800
    m = len(x) // w
    if m == 0:
        return math.sqrt(np.mean(x * x) + 1e-20)
    e = np.mean(x[:m * w].reshape(m, w) ** 2, axis=1)
    keep = e > e.max() * 1e-3
    return math.sqrt(e[keep].mean())


def cmd_scene(args):
    import pyroomacoustics as pra
    opts = {"--rt60": 0.0, "--snr": 5.0, "--utterances": 40, "--seed": 1}
    pos = []
    i = 0
    while i < len(args):
        if args[i] in opts:
            opts[args[i]] = type(opts[args[i]])(args[i + 1])
            i += 2
        else:
            pos.append(args[i])
            i += 1
    voicedir, out_wav, out_tsv = pos[:3]
    datadir = pos[3] if len(pos) > 3 else os.path.join(os.path.dirname(__file__), "..", "data", "speech")
    rng = np.random.default_rng(opts["--seed"])
    rt60, snr_db, nutt = opts["--rt60"], opts["--snr"], opts["--utterances"]
    dim = [6.0, 5.0, 3.0]
    centre = np.array([2.6, 2.2, 0.0])
    if rt60 > 0:
        absorption, order = pra.inverse_sabine(rt60, dim)
        room = pra.ShoeBox(dim, fs=RATE, materials=pra.Material(absorption), max_order=min(order, 40))
    else:
        room = pra.ShoeBox(dim, fs=RATE, max_order=0)
    # Six places people speak from, 1.2 to 2.2 m away; the fan on the floor 1.8 m away.
    places = []
    for k in range(6):
        az = math.radians(-150 + 60 * k + rng.uniform(-15, 15))
        r = rng.uniform(1.2, 2.2)
        places.append((az, [centre[0] + r * math.cos(az), centre[1] + r * math.sin(az), rng.uniform(1.4, 1.75)]))
    fan_az = math.radians(rng.uniform(-180, 180))
    fan_pos = [centre[0] + 1.8 * math.cos(fan_az), centre[1] + 1.8 * math.sin(fan_az), 0.3]
    for _, p in places:
        room.add_source(p)
    room.add_source(fan_pos)
    room.add_microphone_array(pra.MicrophoneArray(np.array([[centre[0] + m[0], centre[1] + m[1], m[2]] for m in MICS]).T, RATE))
    room.compute_rir()
    rirs = room.rir                         # [mic][source]
    real = real_recordings(datadir)
    # The timeline: commands most of the time, then phrases out of the grammar, real recordings
    # and noise bursts; a pause of 1.2 to 3.5 s after each.
    events = []
    t = 1.5
    for u in range(nutt):
        p = rng.uniform()
        kind = "command" if p < 0.55 else "oog" if p < 0.75 else "real" if p < 0.88 else "noise"
        v = int(rng.integers(len(VOICES)))
        if kind == "command":
            i = int(rng.integers(len(COMMANDS)))
            x, text = read_wav(os.path.join(voicedir, "cmd_%d_%02d.wav" % (v, i))), COMMANDS[i]
        elif kind == "oog":
            i = int(rng.integers(len(OUT_OF_GRAMMAR)))
            x, text = read_wav(os.path.join(voicedir, "oog_%d_%02d.wav" % (v, i))), OUT_OF_GRAMMAR[i]
        elif kind == "real":
            x, text = real[int(rng.integers(len(real)))]
        else:
            x, text = burst(rng), "(noise)"
        place = int(rng.integers(len(places)))
        events.append((t, kind, text, place, x))
        t += len(x) / RATE + rng.uniform(1.2, 3.5)
    total = int((t + 1.0) * RATE)
    out = np.zeros((8, total + 20000))
    fan_sig = fan(total, rng)
    fan_mic = [fftconvolve(fan_sig, rirs[m][len(places)])[:total] for m in range(8)]
    fan_rms = math.sqrt(np.mean(fan_mic[0] ** 2))
    rows = ["0.000\t%.3f\tfan\t(fan)\t%.1f" % (total / RATE, math.degrees(fan_az))]
    for t0, kind, text, place, x in events:
        imgs = [fftconvolve(x, rirs[m][place]) for m in range(8)]
        # Every utterance (and burst) stands snr_db over the fan at the first microphone.
        g = fan_rms * 10 ** (snr_db / 20) / active_rms(imgs[0])
        s = int(t0 * RATE)
        for m in range(8):
            out[m, s:s + len(imgs[m])] += g * imgs[m]
        rows.append("%.3f\t%.3f\t%s\t%s\t%.1f" % (t0, t0 + len(x) / RATE, kind, text, math.degrees(places[place][0])))
    for m in range(8):
        out[m, :total] += fan_mic[m]
    out = out[:, :total]
    out *= 0.25 / np.abs(out).max()
    write_wav(out_wav, out.T.reshape(-1), channels=8)
    with open(out_tsv, "w") as f:
        f.write("# start_s\tend_s\tkind\ttext\tbearing_deg (rt60 %.2f s, snr %.1f dB over the fan)\n" % (rt60, snr_db))
        f.write("\n".join(rows) + "\n")


def main():
    if len(sys.argv) >= 3 and sys.argv[1] == "voices":
        cmd_voices(sys.argv[2])
    elif len(sys.argv) >= 5 and sys.argv[1] == "scene":
        cmd_scene(sys.argv[2:])
    else:
        sys.stderr.write(__doc__)
        sys.exit(2)


if __name__ == "__main__":
    main()
