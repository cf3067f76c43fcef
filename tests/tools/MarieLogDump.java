// MarieLogDump: decodes every event of LCM logs with marie's generated Java classes (found in the
// types jar by fingerprint, as lcm-spy does) and prints each field as "path=value".
import java.io.EOFException;
import java.io.FileDescriptor;
import java.io.FileOutputStream;
import java.io.PrintStream;
import java.lang.reflect.Array;
import java.lang.reflect.Field;
import java.lang.reflect.Modifier;
import java.nio.ByteBuffer;
import java.util.Enumeration;
import java.util.HashMap;
import java.util.Map;
import java.util.jar.JarEntry;
import java.util.jar.JarFile;

import lcm.logging.Log;

public class MarieLogDump {
    static final Map<Long, Class<?>> byFingerprint = new HashMap<>();
    static PrintStream out;

    public static void main(String[] args) throws Exception {
        out = new PrintStream(new FileOutputStream(FileDescriptor.out), true, "UTF-8");
        try (JarFile jar = new JarFile(args[0])) {
            for (Enumeration<JarEntry> e = jar.entries(); e.hasMoreElements();) {
                String n = e.nextElement().getName();
                if (!n.startsWith("marie/") || !n.endsWith(".class") || n.contains("$"))
                    continue;
                Class<?> c = Class.forName(n.substring(0, n.length() - 6).replace('/', '.'));
                byFingerprint.put(c.getField("LCM_FINGERPRINT").getLong(null), c);
            }
        }
        for (int i = 1; i < args.length; i++) {
            Log log = new Log(args[i], "r");
            while (true) {
                Log.Event ev;
                try {
                    ev = log.readNext();
                } catch (EOFException eof) {
                    break;
                }
                long fp = ByteBuffer.wrap(ev.data, 0, 8).getLong();
                Class<?> c = byFingerprint.get(fp);
                if (c == null) {
                    out.println("#" + ev.channel + " unknown-type");
                    continue;
                }
                Object msg = c.getConstructor(byte[].class).newInstance((Object) ev.data);
                out.println("#" + ev.channel);
                dump("", msg);
            }
            log.close();
        }
    }

    static void dump(String prefix, Object o) throws Exception {
        for (Field f : o.getClass().getFields()) {
            if (Modifier.isStatic(f.getModifiers()))
                continue;
            value(prefix + f.getName(), f.getType(), f.get(o));
        }
    }

    static void value(String path, Class<?> t, Object v) throws Exception {
        if (t.isArray()) {
            for (int i = 0; i < Array.getLength(v); i++)
                value(path + "[" + i + "]", t.getComponentType(), Array.get(v, i));
        } else if (t == String.class) {
            // LCM's Java runtime reads string bytes as ISO-8859-1 (one char per byte): the
            // UTF-8 text marie sends is those bytes again.
            String s = (String) v;
            boolean bytewise = true;
            for (char ch : s.toCharArray())
                bytewise &= ch <= 0xff;
            if (bytewise)
                s = new String(s.getBytes("ISO-8859-1"), "UTF-8");
            StringBuilder b = new StringBuilder();
            for (char ch : s.toCharArray()) {
                if (ch < 0x20 || ch == 0x7f || ch == '\\')
                    b.append(String.format("\\x%02x", (int) ch));
                else
                    b.append(ch);
            }
            out.println(path + "=" + b);
        } else if (t == double.class) {
            out.println(path + "=" + Double.toString((Double) v));
        } else if (t == float.class) {
            out.println(path + "=" + Double.toString((double) (Float) v));
        } else if (t == boolean.class) {
            out.println(path + "=" + ((Boolean) v ? 1 : 0));
        } else if (t.isPrimitive()) {
            out.println(path + "=" + v);
        } else {
            dump(path + ".", v);
        }
    }
}
