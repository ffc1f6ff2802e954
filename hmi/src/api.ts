// The gRPC services over grpc-web on the page's own origin (cncd serves both), with the
// operator's token as `authorization: Bearer` on every call, exactly as any other client.
import { createClient, type Interceptor } from "@connectrpc/connect";
import { createGrpcWebTransport } from "@connectrpc/connect-web";
import { Constants, Machine, Offsets, Plc, Preview, Programs } from "./gen/cnc/v1/cnc_pb";
import { token } from "./session";

const bearer: Interceptor = (next) => async (req) => {
  const t = token();
  if (t) req.header.set("authorization", `Bearer ${t}`);
  return await next(req);
};

const transport = createGrpcWebTransport({
  baseUrl: location.origin,
  interceptors: [bearer],
});

export const machine = createClient(Machine, transport);
export const programs = createClient(Programs, transport);
export const offsets = createClient(Offsets, transport);
export const plc = createClient(Plc, transport);
export const constants = createClient(Constants, transport);
export const preview = createClient(Preview, transport);
