// A typed event emitter: the session state and sync announce changes through it, so they
// need not know who listens (panels, viewport, selection).
export class Emitter<Events extends object> {
  private readonly listeners: { [K in keyof Events]?: ((payload: Events[K]) => void)[] } = {};

  on<K extends keyof Events>(name: K, listener: (payload: Events[K]) => void): void {
    (this.listeners[name] ??= []).push(listener);
  }

  emit<K extends keyof Events>(name: K, payload: Events[K]): void {
    for (const listener of this.listeners[name] ?? []) listener(payload);
  }
}
